"""The monitor's transforms as plain field values (tf2_msgs/msg/TFMessage): one mapping for the node and replay.

Frames follow the interface contract and REP-103/105: `shaft` is the fixed frame (z up,
origin at the centroid of the head-sheave tangent points), `platform` moves with the
solved pose (/tf), and each head sheave's tangent point A_i is a fixed frame `sheave_<i>`
(/tf_static), axes as `shaft`.
"""
from __future__ import annotations

from collections.abc import Sequence

from ..model.plantfile.plant import Plant
from .fields import FRAME, Fields, Stamp, header

PLATFORM_FRAME = "platform"
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def sheave_frame(cable: int) -> str:
    """The frame of cable `cable`'s head sheave (1..4)."""
    return f"sheave_{cable}"


def transform_stamped(stamp: Stamp, child: str, translation: Sequence[float],
                      rotation: Sequence[float] = IDENTITY) -> Fields:
    """geometry_msgs/TransformStamped of `child` in `shaft`; rotation as a quaternion (x, y, z, w)."""
    x, y, z = translation
    qx, qy, qz, qw = rotation
    return {"header": header(stamp, FRAME), "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z},
                          "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def platform_tf(stamp: Stamp, position: Sequence[float], quaternion: Sequence[float]) -> Fields:
    """/tf of a solved pose: `shaft` -> `platform` at `position` [m], turned by `quaternion` (x, y, z, w)."""
    return {"transforms": [transform_stamped(stamp, PLATFORM_FRAME, position, quaternion)]}


def static_tf(stamp: Stamp, plant: Plant) -> Fields:
    """/tf_static: `shaft` -> `sheave_<i>` at each anchor A_i."""
    return {"transforms": [transform_stamped(stamp, sheave_frame(i), anchor.tolist())
                           for i, anchor in enumerate(plant.anchors, 1)]}
