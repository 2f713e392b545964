"""The plant: geometry, mass and shaft of a four-cable sinking platform, read from YAML.

Frames follow seed 002 and the interface contract: `shaft` has its origin at the
centroid of the head-sheave tangent points A1..A4 with z up; `platform` has its origin
at the centroid of the attachment points B1..B4 and coincides in orientation with
`shaft` when all four cables have equal length.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ...paths import default_plant_file
from ...safe_yaml import YamlLimitError, load_yaml_file
from .error_spec import ModelErrorConfigError, ModelErrorSpec
from .plant_checks import degenerate_points
from .track import TrackConfigError, TrackSpec

CABLE_NAMES = ("cable_1", "cable_2", "cable_3", "cable_4")
DEFAULT_MAX_PAYOUT = 3000.0  # [m] deeper than any shaft sunk with a hanging platform
DEFAULT_MAX_PAYOUT_SPEED = 5.0  # [m/s] sinking winches run below 1 m/s
ALARM_KEYS = ("warning_margin", "critical_margin", "hysteresis", "slack_tolerance")
NOISE_RANGE = (1e-9, 1e9)  # a 1-sigma noise in its channel's unit (m, N, rad, ...): beyond it no sensor, and
                           # the estimator's weights 1/sigma^2 lose their meaning (1e-300 m made them singular)
MAX_WEIGHT = 1e12  # [N] m g of a platform at most (100,000 kt); above ~1e200 N the solvers' squares overflow


class PlantConfigError(ValueError):
    """A plant file is unreadable or a key in it is missing or wrong."""


@dataclass(frozen=True)
class OutlinePoint:
    """One point of the platform outline (platform frame) used for wall clearance."""

    name: str
    position: np.ndarray


@dataclass(frozen=True)
class Sheave:
    """A pulley the rope wraps on its way from the winch to the platform (plant file: geometry.sheaves).

    The rope arrives along `axis` (unit, pointing back towards the winch) and touches the pulley
    at the anchor A_i; the pulley's centre lies `radius` from A_i in its plane. A swivelling
    pulley turns about `axis` so that its plane holds the rope to the platform; a fixed one
    keeps its plane, given by `towards` (unit, perpendicular to `axis`, from A_i to the centre).
    """

    radius: float
    axis: np.ndarray
    swivel: bool = True
    towards: np.ndarray | None = None


@dataclass(frozen=True)
class Plant:
    """Rigid-cable model of the platform: anchors, attachment points, centre of gravity, weight.

    anchors      A_i in `shaft` [m], shape (4, 3)
    attachments  B_i in `platform` [m], shape (4, 3); their centroid is the origin
    cog          C in `platform` [m], shape (3,)
    rectangle    (a, b) when the plant is seed 002's rectangle, else None; the paper's
                 closed-form special cases (3.2, 3.3) need it
    """

    name: str
    anchors: np.ndarray
    attachments: np.ndarray
    cog: np.ndarray
    mass: float
    g: float
    rectangle: tuple[float, float] | None = None
    shaft_radius: float = float("inf")
    shaft_centre: np.ndarray = field(default_factory=lambda: np.zeros(2))
    outline: tuple[OutlinePoint, ...] = ()
    max_payout: float = DEFAULT_MAX_PAYOUT  # [m] longest cable length a winch can pay out
    max_payout_speed: float = DEFAULT_MAX_PAYOUT_SPEED  # [m/s]
    noise: Mapping[str, float] = field(default_factory=dict)  # 1-sigma noise by channel noise key
    alarm: Mapping[str, float] = field(default_factory=dict)  # alarm margins given (monitor.alarm)
    effects: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # effect name -> its parameters
    effect_modules: tuple[str, ...] = ()  # user files defining effects (and channels)
    sheaves: tuple[Sheave, ...] = ()  # one per cable where the plant file describes pulleys (anchors: where ropes meet them)
    effect_bounds: Mapping[str, Mapping[str, tuple[float, float]]] = field(default_factory=dict)  # effect -> param -> (lo, hi)
    model_error: ModelErrorSpec = field(default_factory=ModelErrorSpec)  # how far and fast the model may be off
    track: TrackSpec = field(default_factory=TrackSpec)  # the parameters tracked live, and how they may be used
    raw: Mapping[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def weight(self) -> float:
        """m g [N]."""
        return self.mass * self.g

    @property
    def wrench(self) -> np.ndarray:
        """Gravity as a load, F = (0, 0, -mg, 0, 0, 0) of eq. (7): every solver's default `load` (model.load)."""
        return np.array([0.0, 0.0, -self.weight, 0.0, 0.0, 0.0])

    @property
    def cog_distances(self) -> np.ndarray:
        """r_i = |C B_i| (seed 002, after eq. 2) [m]."""
        return np.linalg.norm(self.attachments - self.cog, axis=1)

    @cached_property
    def moment_scale(self) -> float:
        """A lever arm [m] to make moment residuals relative: max |C B_i|."""
        return float(self.cog_distances.max())

    @cached_property
    def outline_array(self) -> np.ndarray:
        """The outline points in `platform` as one (n, 3) array [m], in the order of `outline`."""
        return np.array([p.position for p in self.outline]).reshape(-1, 3)

    def with_changes(self, **changes: Any) -> Plant:
        """A copy with some fields replaced (for effects and fits)."""
        values = {k: getattr(self, k) for k in self.__dataclass_fields__}
        values.update(changes)
        return Plant(**values)


def seed002_rectangle(a: float, b: float, h: float, k1: float, k2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Anchors, attachments and centre of gravity of seed 002's rectangular plant (Fig. 2)."""
    corners = np.array([[a, b, 0.0], [-a, b, 0.0], [-a, -b, 0.0], [a, -b, 0.0]])
    return corners.copy(), corners.copy(), np.array([k1 * a, k2 * b, -h])


def file_number(value: Any) -> float:
    """A number as a plant file gives it; TypeError for a boolean (YAML's `true` is not 1) or a non-number."""
    if isinstance(value, bool):
        raise TypeError(f"a boolean is not a number: {value!r}")
    return float(value)


def _number(section: Mapping[str, Any], key: str, where: str, positive: bool = False) -> float:
    if key not in section:
        raise PlantConfigError(f"plant file: missing key '{where}{key}'")
    try:
        value = file_number(section[key])
    except (TypeError, ValueError):
        raise PlantConfigError(f"plant file: key '{where}{key}' must be a number, got {section[key]!r}") from None
    if not np.isfinite(value) or (positive and value <= 0.0):
        kind = "finite positive" if positive else "finite"
        raise PlantConfigError(f"plant file: key '{where}{key}' must be a {kind} number, got {value}")
    return value


def _points(value: Any, key: str, count: int | None, dim: int = 3) -> np.ndarray:
    try:
        if any(isinstance(v, bool) for v in np.ravel(np.asarray(value, dtype=object))):
            raise TypeError("booleans are not coordinates")
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise PlantConfigError(f"plant file: key '{key}' must be a list of [x, y, z] points") from None
    expected = (count, dim) if count else (array.shape[0] if array.ndim == 2 else -1, dim)
    if array.ndim != 2 or array.shape != expected or not np.all(np.isfinite(array)):
        raise PlantConfigError(f"plant file: key '{key}' must hold {count or 'some'} finite {dim}-D points, "
                               f"got shape {array.shape}")
    return array


def _outline(section: Any) -> tuple[OutlinePoint, ...]:
    """Outline points of every deck: either explicit points or a circle per deck."""
    if section is None:
        return ()
    if not isinstance(section, Mapping) or "decks" not in section:
        raise PlantConfigError("plant file: key 'outline' must be a mapping with a list 'decks'")
    decks = section["decks"]
    if not isinstance(decks, list):
        raise PlantConfigError(f"plant file: key 'outline.decks' must be a list of decks, got {decks!r}")
    points: list[OutlinePoint] = []
    for index, deck in enumerate(decks):
        where = f"outline.decks[{index}]."
        if not isinstance(deck, Mapping):
            raise PlantConfigError(f"plant file: '{where[:-1]}' must be a mapping")
        name = str(deck.get("name", f"deck_{index + 1}"))
        z = _number(deck, "z", where)
        if "points" in deck:
            xy = _points(deck["points"], where + "points", None, dim=2)
        else:
            radius = _number(deck, "radius", where, positive=True)
            count = deck.get("count", 36)
            if isinstance(count, bool) or not isinstance(count, int) or not 3 <= count <= 10_000:
                raise PlantConfigError(f"plant file: key '{where}count' must be a whole number of points 3..10000, "
                                       f"got {count!r}")
            angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
            xy = radius * np.column_stack([np.cos(angles), np.sin(angles)])
        points += [OutlinePoint(f"{name}/p{k + 1}", np.array([x, y, z])) for k, (x, y) in enumerate(xy)]
    return tuple(points)


def _limits(section: Any) -> tuple[float, float]:
    """Maximum payout [m] and payout speed [m/s] from 'plant.limits' (defaults where not given)."""
    if not isinstance(section, Mapping):
        raise PlantConfigError("plant file: key 'plant.limits' must be a mapping")
    payout, speed = (_number(section, key, "plant.limits.", positive=True) if key in section else default
                     for key, default in (("max_payout", DEFAULT_MAX_PAYOUT), ("max_payout_speed", DEFAULT_MAX_PAYOUT_SPEED)))
    return payout, speed


def _numbers(section: Any, where: str, keys: tuple[str, ...] | None = None) -> dict[str, float]:
    """A mapping of names to finite numbers (only `keys` where given)."""
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise PlantConfigError(f"plant file: key '{where}' must be a mapping of names to numbers")
    if keys is not None:
        unknown = sorted(set(map(str, section)) - set(keys))
        if unknown:
            raise PlantConfigError(f"plant file: unknown key '{where}.{unknown[0]}' (known: {', '.join(keys)})")
    return {str(key): _number(section, key, where + ".") for key in section}


def _noise(section: Any) -> dict[str, float]:
    """`plant.noise`: the 1-sigma noise of each channel by its noise key, each within NOISE_RANGE (the keys
    are checked against the declared channels once user modules are loaded: effects.model)."""
    noise = _numbers(section, "plant.noise")
    low, high = NOISE_RANGE
    for key, value in noise.items():
        if not low <= value <= high:
            raise PlantConfigError(f"plant file: key 'plant.noise.{key}' must be a 1-sigma noise in [{low:g}, "
                                   f"{high:g}] (the channel's unit), got {value:g}")
    return noise


def _effects(section: Any) -> dict[str, dict[str, Any]]:
    """`plant.effects`: {effect name: {enabled: bool, parameter: value, ...}}; the effect layer checks
    the names and values (effects.model.effects_from_mapping)."""
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise PlantConfigError("plant file: key 'plant.effects' must be a mapping of effect names to their parameters")
    out = {}
    for name, spec in section.items():
        if spec is not None and not isinstance(spec, Mapping):
            raise PlantConfigError(f"plant file: key 'plant.effects.{name}' must be a mapping of parameters")
        out[str(name)] = dict(spec or {})
    return out


def _unit(value: Any, key: str) -> np.ndarray:
    vector = _points([value], key, 1)[0]
    norm = float(np.linalg.norm(vector))
    if norm < 1e-9:
        raise PlantConfigError(f"plant file: key '{key}' must be a non-zero direction, got {value!r}")
    return vector / norm


def _sheave(spec: Any, where: str) -> Sheave:
    if not isinstance(spec, Mapping):
        raise PlantConfigError(f"plant file: key '{where}' must be a mapping with radius, axis and swivel")
    unknown = sorted(set(map(str, spec)) - {"radius", "axis", "swivel", "towards"})
    if unknown:
        raise PlantConfigError(f"plant file: unknown key '{where}.{unknown[0]}' (known: radius, axis, swivel, towards)")
    radius = _number(spec, "radius", where + ".")
    if radius < 0.0:
        raise PlantConfigError(f"plant file: key '{where}.radius' must not be negative, got {radius}")
    axis = _unit(spec.get("axis", [0.0, 0.0, -1.0]), where + ".axis")
    swivel = spec.get("swivel", True)
    if not isinstance(swivel, bool):
        raise PlantConfigError(f"plant file: key '{where}.swivel' must be true or false, got {swivel!r}")
    if swivel:
        return Sheave(radius, axis)
    if "towards" not in spec:
        raise PlantConfigError(f"plant file: key '{where}.towards' is missing: a fixed sheave needs the direction "
                               "from its anchor to its centre")
    towards = _unit(spec["towards"], where + ".towards")
    towards = towards - (towards @ axis) * axis
    if np.linalg.norm(towards) < 1e-6:
        raise PlantConfigError(f"plant file: key '{where}.towards' must not be along the sheave's axis")
    return Sheave(radius, axis, False, towards / np.linalg.norm(towards))


def _sheaves(section: Any) -> tuple[Sheave, ...]:
    """`plant.geometry.sheaves`: one mapping for all four pulleys, or a list of four."""
    where = "plant.geometry.sheaves"
    if section is None:
        return ()
    if isinstance(section, Mapping):
        return (_sheave(section, where),) * 4
    if not isinstance(section, list) or len(section) != 4:
        raise PlantConfigError(f"plant file: key '{where}' must be one mapping for all pulleys or a list of four")
    return tuple(_sheave(spec, f"{where}[{i}]") for i, spec in enumerate(section))


def _effect_bounds(section: Any) -> dict[str, dict[str, tuple[float, float]]]:
    """`plant.effect_bounds`: {effect name: {parameter: [low, high]}}, bounds this plant needs instead of an
    effect's own (the effect layer checks the names)."""
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise PlantConfigError("plant file: key 'plant.effect_bounds' must be a mapping of effect names to "
                               "{parameter: [low, high]}")
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for name, params in section.items():
        where = f"plant.effect_bounds.{name}"
        if not isinstance(params, Mapping):
            raise PlantConfigError(f"plant file: key '{where}' must be a mapping of parameters to [low, high]")
        out[str(name)] = {}
        for param, pair in params.items():
            try:
                low, high = (file_number(v) for v in pair)
            except (TypeError, ValueError):
                raise PlantConfigError(f"plant file: key '{where}.{param}' must be [low, high], got {pair!r}") from None
            if not (np.isfinite(low) and np.isfinite(high) and low < high):
                raise PlantConfigError(f"plant file: key '{where}.{param}' must be finite with low < high, "
                                       f"got [{low}, {high}]")
            out[str(name)][str(param)] = (low, high)
    return out


def _modules(value: Any, folder: Path | None) -> tuple[str, ...]:
    """`plant.effect_modules`: file paths, a relative one taken from `folder` (the plant file's) where given."""
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise PlantConfigError("plant file: key 'plant.effect_modules' must be a list of file paths")
    return tuple(str(folder / v) if folder is not None and not Path(v).is_absolute() else v for v in value)


def plant_from_mapping(config: Mapping[str, Any], name: str = "plant", folder: Path | None = None) -> Plant:
    """Build a Plant from the parsed YAML document (read from a file in `folder`, where relative paths in it
    start); errors name the offending key."""
    if not isinstance(config, Mapping) or "plant" not in config:
        raise PlantConfigError("plant file: top-level key 'plant' is missing")
    section = config["plant"]
    if not isinstance(section, Mapping):
        raise PlantConfigError("plant file: key 'plant' must be a mapping")
    if "geometry" not in section or not isinstance(section["geometry"], Mapping):
        raise PlantConfigError("plant file: key 'plant.geometry' is missing or not a mapping")
    geometry = section["geometry"]
    mass = _number(section, "mass", "plant.", positive=True)
    g = _number(section, "g", "plant.", positive=True)
    if not mass * g <= MAX_WEIGHT:
        raise PlantConfigError(f"plant file: key 'plant.mass' = {mass:g} kg: its weight m g = {mass * g:g} N must "
                               f"be finite and at most {MAX_WEIGHT:g} N")
    explicit = [key for key in ("anchors", "attachments", "centre_of_gravity") if key in geometry]
    if explicit:
        if len(explicit) != 3:
            raise PlantConfigError("plant file: give all of 'plant.geometry.anchors', '.attachments' and "
                                   "'.centre_of_gravity', or none")
        anchors = _points(geometry["anchors"], "plant.geometry.anchors", 4)
        attachments = _points(geometry["attachments"], "plant.geometry.attachments", 4)
        cog = _points([geometry["centre_of_gravity"]], "plant.geometry.centre_of_gravity", 1)[0]
        centroid = attachments.mean(axis=0)
        attachments, cog = attachments - centroid, cog - centroid
        rectangle = None
    else:
        a = _number(geometry, "a", "plant.geometry.", positive=True)
        b = _number(geometry, "b", "plant.geometry.", positive=True)
        h = _number(geometry, "h", "plant.geometry.", positive=True)
        k1 = _number(geometry, "k1", "plant.geometry.")
        k2 = _number(geometry, "k2", "plant.geometry.")
        for key, value in (("k1", k1), ("k2", k2)):
            if not -1.0 < value < 1.0:
                raise PlantConfigError(f"plant file: key 'plant.geometry.{key}' must lie in (-1, 1), got {value}")
        anchors, attachments, cog = seed002_rectangle(a, b, h, k1, k2)
        rectangle = (a, b)
    for key, points in (("plant.geometry.anchors", anchors), ("plant.geometry.attachments", attachments)):
        problem = degenerate_points(points)
        if problem:
            raise PlantConfigError(f"plant file: key '{key}': {problem}")
    if cog[2] >= attachments[:, 2].min():
        raise PlantConfigError("plant file: the centre of gravity must lie below the attachment points (hanging platform)")
    shaft = section.get("shaft", {}) or {}
    if not isinstance(shaft, Mapping):
        raise PlantConfigError("plant file: key 'plant.shaft' must be a mapping")
    shaft_radius = _number(shaft, "radius", "plant.shaft.", positive=True) if "radius" in shaft else float("inf")
    shaft_centre = _points([shaft.get("centre", [0.0, 0.0])], "plant.shaft.centre", 1, dim=2)[0]
    max_payout, max_payout_speed = _limits(section.get("limits", {}) or {})
    return Plant(
        name=str(section.get("name", name)),
        anchors=anchors,
        attachments=attachments,
        cog=cog,
        mass=mass,
        g=g,
        rectangle=rectangle,
        shaft_radius=shaft_radius,
        shaft_centre=shaft_centre,
        outline=_outline(section.get("outline")),
        max_payout=max_payout,
        max_payout_speed=max_payout_speed,
        noise=_noise(section.get("noise")),
        alarm=_numbers(section.get("alarm"), "plant.alarm", ALARM_KEYS),
        effects=_effects(section.get("effects")),
        effect_modules=_modules(section.get("effect_modules"), folder),
        sheaves=_sheaves(geometry.get("sheaves")),
        effect_bounds=_effect_bounds(section.get("effect_bounds")),
        model_error=_model_error(section.get("model_error")),
        track=_track(section),
        raw=config,
    )


def _model_error(section: Any) -> ModelErrorSpec:
    """`plant.model_error`: how far and how fast the model may be off (prior.ModelErrorSpec)."""
    try:
        return ModelErrorSpec.from_mapping(section)
    except ModelErrorConfigError as error:
        raise PlantConfigError(f"plant file: {error}") from None


def _track(section: Mapping[str, Any]) -> TrackSpec:
    """`plant.track` and its settings (model.track.TrackSpec; the effect layer checks the names)."""
    try:
        return TrackSpec.from_section(section)
    except TrackConfigError as error:
        raise PlantConfigError(f"plant file: {error}") from None


def load_plant(path: str | Path | None = None) -> Plant:
    """Read a plant YAML file (the bundled seed-002 plant when path is None)."""
    path = Path(path) if path else default_plant_file()
    try:
        config = load_yaml_file(path)
    except OSError as error:
        raise PlantConfigError(f"plant file {path}: cannot be read ({error.strerror})") from None
    except YamlLimitError as error:
        raise PlantConfigError(f"plant file {path}: {error}") from None
    try:
        return plant_from_mapping(config, name=path.stem, folder=path.parent)
    except PlantConfigError as error:
        raise PlantConfigError(f"{path}: {error}") from None
