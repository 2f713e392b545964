"""The 3-D scene an operator watches, as plain field values of a visualization_msgs/msg/MarkerArray.

One sample's scene in `shaft`: the shaft wall (a translucent cylinder from the head
sheaves to below the platform), the head sheaves, every rope from its sheave A_i to its
attachment B_i coloured by its tension (a slack rope grey and dashed), the outline point
of smallest clearance with the gap to the wall and its value, and the alarm level as
colour and text. The first marker deletes the previous scene, so nothing stale stays on
screen when a sample has no pose. The deck outlines do not change: `outline` gives them
once, in `platform`, and a viewer moves them with /tf. The live node and replay both draw
with `SceneBuilder` and thin the scenes by header stamp with `SceneThrottle`.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np

from ..bagio.cdr import Encoder, fixed_encoder
from ..model.plantfile.plant import CABLE_NAMES, Plant
from ..model.statics.result import Solution
from ..monitor.alarm import Alarm, AlarmLevel
from ..monitor.inputs import small_mean
from .fields import FRAME, Fields, Stamp, header
from .frames import PLATFORM_FRAME

# visualization_msgs/msg/Marker constants
SPHERE, CYLINDER, LINE_STRIP, LINE_LIST, SPHERE_LIST, TEXT = 2, 3, 4, 5, 7, 9
ADD, DELETEALL = 0, 3

RGBA = tuple[float, float, float, float]
LEVEL_COLOURS: dict[AlarmLevel, RGBA] = {AlarmLevel.OK: (0.15, 0.75, 0.25, 1.0),
                                         AlarmLevel.WARNING: (1.0, 0.8, 0.0, 1.0),
                                         AlarmLevel.CRITICAL: (1.0, 0.4, 0.0, 1.0),
                                         AlarmLevel.COLLISION: (0.9, 0.0, 0.1, 1.0)}
SLACK_COLOUR: RGBA = (0.6, 0.6, 0.6, 1.0)
WALL_COLOUR: RGBA = (0.55, 0.6, 0.7, 0.25)
DECK_COLOUR: RGBA = (0.9, 0.9, 0.95, 1.0)
SHEAVE_COLOUR: RGBA = (0.3, 0.3, 0.3, 1.0)
TEXT_COLOUR: RGBA = (1.0, 1.0, 1.0, 1.0)
# Rope colour scale, tension as a share of the platform's weight: blue (none) -> cyan -> yellow -> red (all of
# it); saturated all along, so that no taut rope looks like a grey slack one.
TENSION_SCALE = ((0.0, (0.2, 0.3, 1.0)), (1 / 3, (0.0, 0.85, 0.85)), (2 / 3, (1.0, 0.85, 0.0)),
                 (1.0, (0.95, 0.1, 0.05)))

LIVE_RATE = 10.0    # [1/s] the node's default: smooth enough to watch
REPLAY_RATE = 2.0   # [1/s] replay's default: a scene (~4.5 kB) is five times a sample's other outputs
ROPE_WIDTH, DECK_WIDTH = 0.06, 0.05  # [m] line widths
TEXT_HEIGHT = 0.4       # [m]
WALL_BELOW = 3.0        # [m] the wall is drawn this far below the lowest deck
DASH_ENDS = np.linspace(0.0, 1.0, 24)[:, None]  # a slack rope: 12 dashes from A_i to B_i


def tension_colour(share: float) -> RGBA:
    """The rope colour for a tension of `share` times the platform's weight (clipped to 0..1)."""
    share = min(max(share, 0.0), 1.0)
    for (lo, c0), (hi, c1) in zip(TENSION_SCALE, TENSION_SCALE[1:]):
        if share <= hi:
            f = (share - lo) / (hi - lo)
            red, green, blue = (a + f * (b - a) for a, b in zip(c0, c1))
            return (red, green, blue, 1.0)
    raise AssertionError("unreachable: the scale ends at 1.0")


def _xyz(p: Sequence[float]) -> Fields:
    return {"x": p[0], "y": p[1], "z": p[2]}


def _colour(c: RGBA) -> Fields:
    return {"r": c[0], "g": c[1], "b": c[2], "a": c[3]}


# Fields no marker of a scene varies (shared, never modified): `marker` fills them in, and the scene's encoder
# packs them once instead of at every scene.
MARKER = "visualization_msgs/msg/Marker"
SCENE_FIXED: Fields = {"pose": {"orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                       "lifetime": {"sec": 0, "nanosec": 0}, "frame_locked": False, "colors": [],
                       "texture_resource": "", "texture": {"header": header((0, 0), ""), "format": "", "data": []},
                       "uv_coordinates": [], "mesh_resource": "", "mesh_file": {"filename": "", "data": []},
                       "mesh_use_embedded_materials": False}


@lru_cache(maxsize=1)
def scene_encoder() -> Encoder:
    """The CDR encoder of a scene's MarkerArray (each marker with the SCENE_FIXED fields)."""
    return fixed_encoder("visualization_msgs/msg/MarkerArray", {MARKER: SCENE_FIXED})


def points(values: Sequence[Sequence[float]]) -> list[Fields]:
    """geometry_msgs/Point fields of (x, y, z) triples."""
    return [{"x": x, "y": y, "z": z} for x, y, z in values]


def marker(head: Fields, ns: str, kind: int, *, marker_id: int = 0, vertices: list[Fields] | None = None,
           colour: RGBA = TEXT_COLOUR, scale: Sequence[float] = (1.0, 1.0, 1.0),
           position: Sequence[float] = (0.0, 0.0, 0.0), text: str = "", action: int = ADD,
           frame_locked: bool = False) -> Fields:
    """One visualization_msgs/Marker with header `head`, every field given (no lifetime: each scene replaces the
    last); `vertices` as from `points`."""
    return {**SCENE_FIXED, "header": head, "ns": ns, "id": marker_id, "type": kind, "action": action,
            "pose": {"position": _xyz(position), "orientation": SCENE_FIXED["pose"]["orientation"]},
            "scale": _xyz(scale), "color": _colour(colour), "frame_locked": frame_locked,
            "points": vertices or [], "text": text}


class SceneState(NamedTuple):
    """What a sample's scene shows of its solution and alarm, in plain numbers: replay's second process sends
    it to the process that draws the scenes (a Solution and an Alarm took 140 us a scene to pickle and
    unpickle, as much as drawing it)."""

    lengths: list[float]                  # the solution's rope lengths [m] (NaN: not known)
    position: list[float] | None          # the platform's position [m] (None: no pose)
    up: list[float] | None                # its rotation's third row: body point p is at height position[2] + up . p
    points_b: list[list[float]] | None    # the attachments B_i in `shaft` [m]
    tensions: list[float] | None          # [N]
    spans: list[float] | None             # [m] from A_i to B_i
    taut: frozenset[int]                  # the taut ropes (1..4)
    level: AlarmLevel
    clearance: tuple[float, str, list[float]] | None  # [m], the outline point nearest the wall, where it is in `shaft`
    reason: str

    @classmethod
    def of(cls, solution: Solution, alarm: Alarm) -> SceneState:
        def listed(values: np.ndarray | None) -> Any:
            return None if values is None else values.tolist()

        position, rotation = (solution.position, solution.rotation) if solution.ok else (None, None)
        clearance = alarm.clearance
        return cls(solution.lengths.tolist(), listed(position), None if rotation is None else rotation[2].tolist(),
                   listed(solution.points_b), listed(solution.tensions), listed(solution.spans),
                   frozenset(solution.taut_set), alarm.level,
                   None if clearance is None else (float(clearance.value), clearance.point_name,
                                                   clearance.point_shaft.tolist()),
                   alarm.reason)


class SceneBuilder:
    """The scene of one plant: what does not move is computed once."""

    def __init__(self, plant: Plant):
        self.plant = plant
        decks: dict[str, list[int]] = {}
        for k, point in enumerate(plant.outline):
            decks.setdefault(point.name.split("/", 1)[0], []).append(k)
        body = plant.outline_array
        self.decks = [points(body[rows + rows[:1]].tolist()) for rows in decks.values()]  # closed, in `platform`
        self.sheaves = points(plant.anchors.tolist())

    def scene(self, stamp: Stamp, solution: Solution, alarm: Alarm) -> Fields:
        """The MarkerArray fields of one sample (wall, sheaves and alarm always; ropes and closest point with a
        pose or a clearance)."""
        return self.draw(stamp, SceneState.of(solution, alarm))

    def draw(self, stamp: Stamp, state: SceneState) -> Fields:
        """`scene`, from what it shows of the solution and alarm."""
        head = header(stamp, FRAME)
        markers = [marker(head, "", 0, action=DELETEALL),
                   marker(head, "sheaves", SPHERE_LIST, vertices=self.sheaves, colour=SHEAVE_COLOUR,
                          scale=(0.4, 0.4, 0.4))]
        level_colour = LEVEL_COLOURS[state.level]
        known = [length for length in state.lengths if not math.isnan(length)]  # np.nanmean's, the same to the bit
        bottom = -small_mean(known) if any(map(math.isfinite, known)) else 0.0
        label_at = (*self.plant.shaft_centre.tolist(), bottom + 2.0)
        if state.position is not None and state.up is not None:
            heights = state.position[2] + self.plant.outline_array @ np.array(state.up)
            bottom = float(heights.min())
            label_at = (*state.position[:2], float(heights.max()) + 5.0)
            markers += self._ropes(head, state)
        markers.append(self._wall(head, bottom - WALL_BELOW))
        markers += self._closest(head, state, level_colour)
        clearance = "" if state.clearance is None else f", clearance {state.clearance[0]:.3f} m"
        markers.append(marker(head, "alarm", TEXT, colour=level_colour, scale=(0.0, 0.0, TEXT_HEIGHT * 1.5),
                              position=label_at, text=f"{state.level.name}{clearance}: {state.reason}"))
        return {"markers": markers}

    def _wall(self, head: Fields, bottom: float) -> Fields:
        centre = (*self.plant.shaft_centre.tolist(), bottom / 2.0)
        diameter = 2.0 * self.plant.shaft_radius
        return marker(head, "shaft_wall", CYLINDER, colour=WALL_COLOUR, scale=(diameter, diameter, -bottom),
                      position=centre)

    def outline(self, stamp: Stamp) -> Fields:
        """The MarkerArray fields of the platform's deck outlines in `platform`, locked to that frame: sent once
        (latched, like a robot description), a viewer draws them at the pose of /tf at every solved sample."""
        head = header(stamp, PLATFORM_FRAME)
        return {"markers": [marker(head, "decks", LINE_STRIP, marker_id=k, vertices=deck, colour=DECK_COLOUR,
                                   scale=(DECK_WIDTH, 0.0, 0.0), frame_locked=True)
                            for k, deck in enumerate(self.decks)]}

    def _ropes(self, head: Fields, state: SceneState) -> list[Fields]:
        """Rope i from A_i to B_i: coloured by tension when taut, grey and dashed when slack; a label near B_i."""
        assert state.tensions is not None and state.points_b is not None  # drawn for a solved pose only
        assert state.spans is not None
        out = []
        weight = self.plant.weight
        for i, (name, a, b) in enumerate(zip(CABLE_NAMES, self.plant.anchors, np.array(state.points_b))):
            tension = state.tensions[i]
            if (i + 1) in state.taut:
                out.append(marker(head, "ropes", LINE_STRIP, marker_id=i, vertices=points([a.tolist(), b.tolist()]),
                                  colour=tension_colour(tension / weight), scale=(ROPE_WIDTH, 0.0, 0.0)))
                label = f"{name} {tension / 1000.0:.1f} kN"
            else:
                dashes = points((a + DASH_ENDS * (b - a)).tolist())
                out.append(marker(head, "ropes", LINE_LIST, marker_id=i, vertices=dashes, colour=SLACK_COLOUR,
                                  scale=(ROPE_WIDTH, 0.0, 0.0)))
                label = f"{name} slack, loose by {state.lengths[i] - state.spans[i]:.3f} m"
            towards_a = a - b
            distance = max(math.sqrt(towards_a.dot(towards_a)), 1e-9)  # np.linalg.norm's sum, without its checks
            label_at = [p + 3.0 * (d / distance) for p, d in zip(b.tolist(), towards_a.tolist())]
            out.append(marker(head, "rope_labels", TEXT, marker_id=i, scale=(0.0, 0.0, TEXT_HEIGHT),
                              position=label_at, text=label))
        return out

    def _closest(self, head: Fields, state: SceneState, colour: RGBA) -> list[Fields]:
        """The outline point nearest the wall, the gap from it to the wall, and the clearance as text."""
        if state.clearance is None or not math.isfinite(state.clearance[0]):
            return []
        value, name, shaft = state.clearance
        point = np.array(shaft)
        offset = point[:2] - self.plant.shaft_centre
        radial = offset / max(math.hypot(*offset.tolist()), 1e-9)
        wall = (*(self.plant.shaft_centre + self.plant.shaft_radius * radial).tolist(), shaft[2])
        return [marker(head, "closest_point", SPHERE, colour=colour, scale=(0.3, 0.3, 0.3), position=shaft),
                marker(head, "closest_point", LINE_LIST, marker_id=1, vertices=points([shaft, wall]),
                       colour=colour, scale=(ROPE_WIDTH, 0.0, 0.0)),
                marker(head, "closest_point", TEXT, marker_id=2, colour=colour, scale=(0.0, 0.0, TEXT_HEIGHT),
                       position=(point + np.array([0.0, 0.0, 0.8])).tolist(),
                       text=f"{value:.3f} m at {name}")]


class SceneThrottle:
    """At most `rate` scenes per second of header stamps: a scene is due when `period` has passed since the last
    one, or the stamps went back by more than that, as when a simulation restarts (a sample made at another
    winch's message, stamped a little before the last, is not a restart)."""

    def __init__(self, rate: float):
        if not rate > 0.0:
            raise ValueError(f"scene rate must be positive, got {rate}")
        self.period = 1.0 / rate
        self.last = -math.inf

    def due(self, stamp: float) -> bool:
        if self.last - self.period <= stamp < self.last + self.period:
            return False
        self.last = stamp
        return True
