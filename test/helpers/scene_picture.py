"""A picture of one 3-D scene as a viewer reads it: markers in their frames, frame-locked ones moved by /tf.

Input is the decoded JSON of Foxglove's readers (test/viewer/read_bag.mjs): the scene, the
latched deck outlines and the platform transform of the scene's stamp. Left, the whole
shaft from the head sheaves; right, the platform close up, with the rope labels, the
closest point and the alarm.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial.transform import Rotation

from cable_winch_monitor.messages.scene import CYLINDER, LINE_LIST, LINE_STRIP, SPHERE, SPHERE_LIST, TEXT


def _points(marker: dict[str, Any]) -> np.ndarray:
    return np.array([[p["x"], p["y"], p["z"]] for p in marker["points"]]).reshape(-1, 3)


def _in_shaft(marker: dict[str, Any], platform: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    points = _points(marker)
    if marker["header"]["frame_id"] == "platform":
        rotation, position = platform
        points = position + points @ rotation.T
    return points


def _colour(marker: dict[str, Any]) -> tuple[float, ...]:
    c = marker["color"]
    return c["r"], c["g"], c["b"], max(c["a"], 0.35)


def _clip(a: np.ndarray, b: np.ndarray, top: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The part of segment a-b at or betop the height `top` (None if there is none)."""
    if a[2] <= top and b[2] <= top:
        return a, b
    if a[2] > top and b[2] > top:
        return None
    inside, outside = (a, b) if a[2] <= top else (b, a)
    f = (top - inside[2]) / (outside[2] - inside[2])
    return inside, inside + f * (outside - inside)


def _draw(ax: Any, markers: list[dict[str, Any]], platform: tuple[np.ndarray, np.ndarray], top: float | None,
          labels: bool) -> None:
    for m in markers:
        kind, colour = m["type"], _colour(m)
        if kind == CYLINDER:
            p, s = m["pose"]["position"], m["scale"]
            theta = np.linspace(0.0, 2.0 * np.pi, 73)
            z_low, z_high = p["z"] - s["z"] / 2, p["z"] + s["z"] / 2
            z_high = min(z_high, top) if top is not None else z_high
            x, y = p["x"] + s["x"] / 2 * np.cos(theta), p["y"] + s["y"] / 2 * np.sin(theta)
            for z in np.linspace(z_low, z_high, 6 if top is not None else 2):
                ax.plot(x, y, z, color=colour, linewidth=0.6)
            for k in range(0, 72, 9):
                ax.plot([x[k]] * 2, [y[k]] * 2, [z_low, z_high], color=colour, linewidth=0.6)
        elif kind in (LINE_STRIP, LINE_LIST):
            points = _in_shaft(m, platform)
            pairs = zip(points[:-1], points[1:]) if kind == LINE_STRIP else zip(points[::2], points[1::2])
            for a, b in pairs:
                segment = _clip(a, b, top) if top is not None else (a, b)
                if segment is not None:
                    ax.plot(*np.array(segment).T, color=colour, linewidth=2.2 if m["ns"] == "ropes" else 1.4)
        elif kind in (SPHERE, SPHERE_LIST):
            points = _in_shaft(m, platform) if kind == SPHERE_LIST else np.array([[m["pose"]["position"][k]
                                                                                   for k in "xyz"]])
            if top is not None:
                points = points[points[:, 2] <= top]
            ax.scatter(*points.T, color=colour, s=30 if kind == SPHERE else 12, depthshade=False)
        elif kind == TEXT and labels:
            p = m["pose"]["position"]
            if top is None or p["z"] <= top:
                ax.text(p["x"], p["y"], p["z"], m["text"], color=_colour(m), fontsize=8)


def render(scene: dict[str, Any], outline: dict[str, Any], transform: dict[str, Any], path: Path) -> None:
    """Draw `scene` and the deck `outline` (decoded MarkerArrays) with the platform at `transform` (a decoded
    TransformStamped)."""
    t, q = transform["transform"]["translation"], transform["transform"]["rotation"]
    platform = (Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).as_matrix(),
                np.array([t["x"], t["y"], t["z"]]))
    markers = [m for m in scene["markers"] + outline["markers"] if m["action"] == 0]
    plt.style.use("dark_background")  # as Foxglove's 3-D panel
    fig = plt.figure(figsize=(10, 6.2), dpi=90)
    whole = fig.add_subplot(1, 3, 1, projection="3d")
    _draw(whole, markers, platform, None, labels=False)
    whole.set_box_aspect((1, 1, 3))
    whole.set_title("shaft, sheaves to platform", fontsize=9)
    close = fig.add_subplot(1, 3, (2, 3), projection="3d")
    heights = [p["z"] for m in markers if m["ns"] == "decks" for p in m["points"]]
    top = platform[1][2] + max(heights) + 6.0
    _draw(close, markers, platform, top, labels=True)
    close.set_zlim(platform[1][2] + min(heights) - 3.0, top)
    close.set_xlim(-4.5, 4.5)
    close.set_ylim(-4.5, 4.5)
    close.set_box_aspect((1, 1, 1.6))
    close.view_init(elev=12, azim=-60)
    stamp = scene["markers"][0]["header"]["stamp"]
    close.set_title(f"platform at t = {stamp['sec'] + stamp['nanosec'] * 1e-9:.1f} s (shaft frame, m)", fontsize=9)
    for ax in (whole, close):
        ax.tick_params(labelsize=6)
        ax.grid(False)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_pane_color((0.12, 0.12, 0.14, 1.0))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
