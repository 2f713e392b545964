"""Simulation scenarios: YAML files checked against the defaults below, with --set overrides.

Every key has a default here, so a scenario file states only what it changes; a key that
is not known, or a value of the wrong kind, is an error that names the dotted key.
"""
from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..paths import config_dir
from ..safe_yaml import YamlLimitError, load_yaml_file, parse_yaml
from .keys import ScenarioError, check_item, check_value

# None marks an optional value; its kind is in OPTIONAL.
DEFAULTS: dict[str, Any] = {
    "description": "",
    "plant": None,          # plant YAML; None: the bundled seed-002 plant
    "seed": 0,              # random seed (--seed overrides)
    "duration": None,       # [s] None: the end of the profile + 5 s
    "start_time": 0.0,      # [s] header stamp of t = 0 (sim time)
    "profile": {
        "start_length": 50.0,   # [m] payout of every cable at t = 0
        "segments": [],         # in order: {move: m (+ lower, - hoist), speed: m/s, accel: m/s^2} or {stop: s}
    },
    "ropes": {
        "model": "rigid",       # rigid | elastic
        "EA": 5.0e8,            # [N] axial stiffness of each rope (elastic)
    },
    "effects": {},              # physical effects hidden in the truth (sim/physics.py): {name: {parameter: value, enabled: bool}}
    "effect_modules": [],       # user modules (paths; a relative one beside the scenario) whose measurement effects
                                # `effects` may name; --effect-module adds to them
    "shaft_air": {              # air temperature in the shaft: mean + drift t + amplitude sin(2 pi t / period)
        "temperature": 15.0,    # [deg C] at t = 0
        "amplitude": 0.0,       # [K] ventilation cycle
        "period": 300.0,        # [s]
        "drift": 0.0,           # [K/s]
    },
    "sync": {
        "sigma": 0.0,           # [m] stationary standard deviation of each winch's random drift (Ornstein-Uhlenbeck)
        "tau": 30.0,            # [s] its correlation time
        "events": [],           # {winch: 1-4, lag: m, start: s, duration: s, hold: s}: winch pays out `lag` less
        "drives": "encoders",   # encoders: the winches pay out what their encoders report plus the errors above (an
                                # encoder error moves the rope); ropes: the ropes are paid out so, kept in step by a
                                # measurement of their own, and the encoders the monitor reads report them through
                                # the hidden encoder errors
    },
    "sensors": {
        "latency": 0.004,       # [s] mean delay of the bag's receive time after the header stamp
        "jitter": 0.002,        # [s] 1-sigma timing jitter of every sample
        "joint_states": {
            "rate": 10.0,           # [Hz]
            "per_winch": False,     # True: /winch_<i>/joint_states, one name each; False: /winch/joint_states
            "length_noise": 0.001,  # [m] encoder
            "velocity": True,       # publish payout speed
            "velocity_noise": 0.002,  # [m/s]
            "effort": True,         # publish load-pin tension
            "tension_noise": 150.0,   # [N] load pin
        },
        "imu": {                    # inclinometer: roll and pitch
            "enabled": False,
            "rate": None,           # [Hz] None: one reading per winch sample, `lag_min`..`lag_max` after it
            "lag_min": 0.030,       # [s]
            "lag_max": 0.040,       # [s]
            "noise": 1.745e-4,      # [rad] (0.01 deg)
        },
        "position": {"enabled": False, "rate": 2.0, "noise": 0.005,      # depth gauge: [Hz], [m]
                     "horizontal": False},  # True: x and y too (motion capture)
        "temperature": {"enabled": False, "rate": 1.0, "noise": 0.1},   # shaft air thermometer: [Hz], [K]
        "faults": [],               # {sensor, kind: stuck | offset | silent, start, duration, value, roll, pitch}
    },
}
OPTIONAL = {"plant": str, "duration": float, "rate": float}
MOVE = {"move": float, "speed": float, "accel": float}
STOP = {"stop": float}
EVENT = {"winch": int, "lag": float, "start": float, "duration": float, "hold": float}
EVENT_OPTIONAL = {"hold"}
ROPE_MODELS = ("rigid", "elastic")
DRIVES = ("encoders", "ropes")


def _segment(item: Any, where: str) -> dict:
    if isinstance(item, Mapping) and "stop" in item:
        return check_item(item, STOP, where)
    return check_item(item, MOVE, where)


def _fault(item: Any, where: str) -> dict:
    from .faults import check_fault

    return check_fault(item, where)


LIST_ITEMS = {"effect_modules": lambda item, where: check_value(item, str, where),
              "profile.segments": _segment,
              "sync.events": lambda item, where: check_item(item, EVENT, where, EVENT_OPTIONAL),
              "sensors.faults": _fault}


def _merge(defaults: Mapping[str, Any], given: Any, where: str) -> dict[str, Any]:
    """`given` over `defaults`, checking every key and the kind of every value."""
    if not isinstance(given, Mapping):
        raise ScenarioError(f"key '{where or 'scenario'}' must be a mapping, got {given!r}")
    merged = copy.deepcopy(dict(defaults))
    for key, value in given.items():
        path = f"{where}.{key}" if where else str(key)
        if key not in defaults:
            raise ScenarioError(f"unknown key '{path}' (known: {', '.join(defaults)})")
        default = defaults[key]
        if path == "effects":  # free-form: checked against the effect registry in _check_physics
            if not isinstance(value, Mapping):
                raise ScenarioError(f"key 'effects' must be a mapping of effect names to parameters, got {value!r}")
            merged[key] = {str(name): copy.deepcopy(spec) for name, spec in value.items()}
        elif isinstance(default, Mapping):
            merged[key] = _merge(default, value, path)
        elif isinstance(default, list):
            if not isinstance(value, list):
                raise ScenarioError(f"key '{path}' must be a list, got {value!r}")
            merged[key] = [LIST_ITEMS[path](item, f"{path}[{i}]") for i, item in enumerate(value)]
        elif default is None:
            merged[key] = None if value is None else check_value(value, OPTIONAL[key], path)
        else:
            merged[key] = check_value(value, type(default), path)
    return merged


def _check_physics(config: dict[str, Any]) -> None:
    from ..effects import EffectError, Registry
    from .hidden import effects_section

    try:
        registry = Registry(config["effect_modules"])
    except EffectError as error:
        raise ScenarioError(f"key 'effect_modules': {error}") from None
    effects_section(config["effects"], "effects", registry)
    if config["ropes"]["model"] not in ROPE_MODELS:
        raise ScenarioError(f"key 'ropes.model' must be one of {', '.join(ROPE_MODELS)}, "
                            f"got {config['ropes']['model']!r}")
    if config["sync"]["drives"] not in DRIVES:
        raise ScenarioError(f"key 'sync.drives' must be one of {', '.join(DRIVES)}, got {config['sync']['drives']!r}")
    positive = [("ropes.EA", config["ropes"]["EA"]), ("sync.tau", config["sync"]["tau"]),
                ("profile.start_length", config["profile"]["start_length"])]
    positive += [(f"sensors.{name}.rate", config["sensors"][name]["rate"])
                 for name in ("joint_states", "imu", "position", "temperature")
                 if config["sensors"][name]["rate"] is not None]
    positive.append(("shaft_air.period", config["shaft_air"]["period"]))
    for i, segment in enumerate(config["profile"]["segments"]):
        positive += [(f"profile.segments[{i}].{k}", segment[k]) for k in ("speed", "accel") if k in segment]
    if config["duration"] is not None:
        positive.append(("duration", config["duration"]))
    for where, value in positive:
        if not value > 0.0:
            raise ScenarioError(f"key '{where}' must be positive, got {value}")
    imu = config["sensors"]["imu"]
    if not 0.0 <= imu["lag_min"] <= imu["lag_max"]:
        raise ScenarioError(f"keys 'sensors.imu.lag_min' and 'lag_max' must satisfy 0 <= lag_min <= lag_max, "
                            f"got {imu['lag_min']} and {imu['lag_max']}")
    payout = config["profile"]["start_length"]
    for i, segment in enumerate(config["profile"]["segments"]):
        payout += segment.get("move", 0.0)
        if payout <= 0.0:
            raise ScenarioError(f"key 'profile.segments[{i}].move' hoists the cables to a payout of {payout:g} m")
    for i, event in enumerate(config["sync"]["events"]):
        if not 1 <= event["winch"] <= 4:
            raise ScenarioError(f"key 'sync.events[{i}].winch' must be 1..4, got {event['winch']}")


def apply_override(config: dict[str, Any], assignment: str) -> None:
    """Apply one `dotted.key=value` (value in YAML syntax; list items by index: sync.events.0.lag=0.2)."""
    key, sep, text = assignment.partition("=")
    if not sep or not key:
        raise ScenarioError(f"--set {assignment!r}: expected key=value, e.g. sync.sigma=0.01")
    try:
        value = parse_yaml(text)
    except YamlLimitError:
        value = text
    parts = key.split(".")
    target: Any = config
    for depth, part in enumerate(parts[:-1]):
        where = ".".join(parts[:depth + 1])
        if isinstance(target, list):
            if not part.isdigit() or int(part) >= len(target):
                raise ScenarioError(f"--set {key}: '{'.'.join(parts[:depth])}' has {len(target)} items, no item {part}")
            target = target[int(part)]
        else:
            target = target.setdefault(part, {})
        if not isinstance(target, (dict, list)):
            raise ScenarioError(f"--set {key}: '{where}' is a value, not a section")
    last = parts[-1]
    if isinstance(target, list):
        if not last.isdigit() or int(last) >= len(target):
            raise ScenarioError(f"--set {key}: the list has {len(target)} items, no item {last}")
        target[int(last)] = value
    else:
        target[last] = value


def scenario_path(name: str) -> Path:
    """A scenario file: the path as given, else the bundled config/scenarios/<name>.yaml."""
    path = Path(name)
    bundled = config_dir() / "scenarios" / f"{name}.yaml"
    return bundled if not path.exists() and bundled.is_file() else path


def load_scenario(path: str | Path, overrides: Sequence[str] = (), seed: int | None = None,
                  effect_modules: Sequence[str | Path] = ()) -> dict[str, Any]:
    """The checked scenario: file, then `--set` overrides, then `seed` if given; `effect_modules` (--effect-module)
    after the file's own."""
    path = Path(path)
    try:
        raw = load_yaml_file(path) or {}
    except OSError as error:
        raise ScenarioError(f"scenario {path}: cannot be read ({error.strerror})") from None
    except YamlLimitError as error:
        raise ScenarioError(f"scenario {path}: {error}") from None
    try:
        if not isinstance(raw, dict):
            raise ScenarioError("the file must hold a mapping of keys")
        for assignment in overrides:
            apply_override(raw, assignment)
        if seed is not None:
            raw["seed"] = seed
        config = _merge(DEFAULTS, raw, "")
        config["effect_modules"] = [str((path.parent / module).resolve()) for module in config["effect_modules"]] + \
            [str(Path(module).resolve()) for module in effect_modules]
        _check_physics(config)
    except ScenarioError as error:
        raise ScenarioError(f"scenario {path}: {error}") from None
    config["name"] = path.stem
    if config["plant"] is not None and not Path(config["plant"]).is_absolute():
        beside = path.parent / config["plant"]  # a relative plant file is looked for beside the scenario first
        config["plant"] = str(beside) if beside.is_file() else config["plant"]
    return config
