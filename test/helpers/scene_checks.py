"""Checks of a received 3-D scene (visualization_msgs/MarkerArray) and transforms against the physics of a solve.

Messages are read by attribute, so rclpy messages (live node) and rosbags messages (replayed
bags) are checked by the same code.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cable_winch_monitor.messages.scene import (
    DELETEALL,
    LEVEL_COLOURS,
    LINE_LIST,
    LINE_STRIP,
    SLACK_COLOUR,
    tension_colour,
)
from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES, Plant
from cable_winch_monitor.model.statics.result import Solution
from cable_winch_monitor.monitor.alarm import AlarmLevel

LENGTH_TOL = 1e-3  # [m]


def xyz(p: Any) -> np.ndarray:
    return np.array([p.x, p.y, p.z])


def rgba(c: Any) -> tuple[float, ...]:
    return tuple(round(float(v), 6) for v in (c.r, c.g, c.b, c.a))


def by_ns(scene: Any) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    for m in scene.markers:
        out.setdefault(m.ns, []).append(m)
    return out


def check_transform(transform: Any, parent: str, child: str, position: np.ndarray, quaternion: np.ndarray) -> None:
    assert (transform.header.frame_id, transform.child_frame_id) == (parent, child)
    t, q = transform.transform.translation, transform.transform.rotation
    np.testing.assert_allclose(xyz(t), position, atol=1e-9)
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], quaternion, atol=1e-9)


def check_static_tf(message: Any, plant: Plant) -> None:
    """/tf_static: one frame per head sheave, at A_i, axes as `shaft`."""
    assert [t.child_frame_id for t in message.transforms] == [f"sheave_{i}" for i in range(1, 5)]
    for transform, anchor in zip(message.transforms, plant.anchors):
        check_transform(transform, "shaft", transform.child_frame_id, anchor, np.array([0.0, 0.0, 0.0, 1.0]))


def check_scene(scene: Any, plant: Plant, solution: Solution, level: AlarmLevel, clearance: float) -> None:
    """The scene of a solved sample drawn as it should be: ropes from A_i to B_i no longer than their
    length (taut ones exactly as long), slack ropes grey and dashed, taut ropes in the colour of their
    share of the weight, the closest point on the wall side at its clearance, the alarm."""
    assert scene.markers[0].action == DELETEALL, "each scene replaces the last"
    markers = by_ns(scene)
    ropes = sorted(markers["ropes"], key=lambda m: m.id)
    assert [m.id for m in ropes] == [0, 1, 2, 3]
    for i, rope in enumerate(ropes):
        ends = np.array([xyz(p) for p in rope.points])
        np.testing.assert_allclose(ends[0], plant.anchors[i], atol=1e-9)
        np.testing.assert_allclose(ends[-1], solution.points_b[i], atol=1e-9)
        span = float(np.linalg.norm(ends[-1] - ends[0]))
        assert span <= solution.lengths[i] + LENGTH_TOL, f"{CABLE_NAMES[i]} drawn longer than its rope"
        if (i + 1) in solution.taut_set:
            assert rope.type == LINE_STRIP and abs(span - solution.lengths[i]) < LENGTH_TOL
            assert rgba(rope.color) == pytest.approx(tension_colour(solution.tensions[i] / plant.weight), abs=1e-6)
        else:
            assert rope.type == LINE_LIST and len(rope.points) > 2 and rgba(rope.color) == SLACK_COLOUR
    labels = {m.id: m.text for m in markers["rope_labels"]}
    for i in range(4):
        assert labels[i].startswith(CABLE_NAMES[i]) and (("slack" in labels[i]) != ((i + 1) in solution.taut_set))
    sphere, gap, text = sorted(markers["closest_point"], key=lambda m: m.id)
    point, (start, end) = xyz(sphere.pose.position), (xyz(p) for p in gap.points)
    np.testing.assert_allclose(start, point)
    assert abs(np.hypot(*(end[:2] - plant.shaft_centre)) - plant.shaft_radius) < 1e-9, "the gap ends on the wall"
    assert abs(np.hypot(*(point[:2] - plant.shaft_centre)) + clearance - plant.shaft_radius) < 1e-9
    assert f"{clearance:.3f} m" in text.text
    alarm = markers["alarm"][0]
    assert alarm.text.startswith(level.name) and rgba(alarm.color) == LEVEL_COLOURS[level]
    assert rgba(sphere.color) == LEVEL_COLOURS[level]
    assert all(m.header.frame_id == "shaft" for m in scene.markers)


def check_outline(outline: Any, plant: Plant) -> None:
    """The deck outlines: closed, in `platform` and locked to it, the plant file's points."""
    decks = sorted(outline.markers, key=lambda m: m.id)
    assert all(d.ns == "decks" and d.header.frame_id == "platform" and d.frame_locked for d in decks)
    outlines = [np.array([xyz(p) for p in d.points]) for d in decks]
    assert all(np.array_equal(o[0], o[-1]) for o in outlines), "each deck outline is closed"
    np.testing.assert_allclose(np.concatenate([o[:-1] for o in outlines]), plant.outline_array)
