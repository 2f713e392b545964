"""Recordings and plant files for judging the tracked plant parameters (config/scenarios/site_tracking.yaml).

The recordings are the simulator's (its own root-found equilibrium, sim/truth.py) at site noise: lowering
and hoisting with stops on elastic ropes (EA 6.8e7 N, 58 N/m). The plant files track what a site tracks
(`bench.plants.tracking_plant_file`: the ropes' stiffness and weight, the encoders' zeros to 1 cm, the load
pins' zeros).
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bench.plants import SITE_EA, SITE_WEIGHT
from cable_winch_monitor.messages.outputs import DIAGNOSTICS, OUTPUT_TYPES, PARAMETERS
from cable_winch_monitor.model.plantfile.plant import Plant, load_plant
from cable_winch_monitor.model.plantfile.track import TrackSpec
from cable_winch_monitor.sim.simulate import TRUTH_FILE

NAMES = ["rope_elasticity.EA", "rope_weight.w"] + [f"encoder_offset.d_{i}" for i in range(1, 5)] + \
    [f"load_pin_calibration.zero_{i}" for i in range(1, 5)]
TRUTH = np.array([SITE_EA, SITE_WEIGHT] + [0.0] * 8)  # the simulator's value of each of NAMES
SLIP = -0.05  # [m] what winch 1's encoder reports beyond the payout once it slipped: encoder_offset.d_1 = +0.05
MOVING = 0.02  # [m/s] payout speed beyond which the stage moves


def untracked(path: Path) -> Plant:
    """The plant of a plant file, tracking nothing."""
    return load_plant(path).with_changes(track=TrackSpec())


class Tracked(NamedTuple):
    """/model/parameters of an output bag as arrays over its messages (rows) and NAMES (columns)."""

    stamps: np.ndarray    # [s]
    values: np.ndarray
    sigmas: np.ndarray
    in_use: np.ndarray
    used: np.ndarray
    excited: np.ndarray
    drifting: np.ndarray
    since: np.ndarray
    tolerances: np.ndarray

    def at(self, stamp: float) -> int:
        """The last message stamped at or before `stamp`."""
        return int(np.searchsorted(self.stamps, stamp, side="right")) - 1

    def column(self, name: str) -> int:
        """The column of a parameter `effect.param`."""
        return NAMES.index(name)


def tracked(bag: Path) -> Tracked:
    """The /model/parameters an output bag holds, read back with the package's reader."""
    messages = [item.message for item in BagReader(bag, {PARAMETERS: OUTPUT_TYPES[PARAMETERS]})]
    assert messages and all(list(m.names) == NAMES for m in messages)
    stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in messages])
    fields = ("values", "sigmas", "in_use", "values_in_use", "excited", "drifting", "drifting_since", "tolerances")
    return Tracked(stamps, *(np.array([list(getattr(m, name)) for m in messages]) for name in fields))


def tracking_statuses(bag: Path) -> list[tuple[float, int, str, dict[str, str]]]:
    """Each /diagnostics message's parameter-tracking status: log time [s], level, message, values (every
    message has one, before the first sample too)."""
    out = []
    for item in BagReader(bag, {DIAGNOSTICS: OUTPUT_TYPES[DIAGNOSTICS]}):
        found = [s for s in item.message.status if s.name.endswith("parameter tracking")]
        assert len(found) == 1, f"/diagnostics at {item.log_time * 1e-9:.3f} s: {[s.name for s in item.message.status]}"
        status = found[0]
        out.append((item.log_time * 1e-9, status.level, status.message, {v.key: v.value for v in status.values}))
    return out


def moving_time(bag: Path) -> tuple[np.ndarray, np.ndarray]:
    """The truth's sample stamps [s] and the time [s] the stage had moved by each (payout speed beyond MOVING)."""
    with (bag / TRUTH_FILE).open() as file:
        rows = [row for row in csv.DictReader(file) if row["stream"] == "joint_states"]
    stamps = np.array([float(row["time"]) for row in rows])
    payout = np.array([[float(row[f"length_{i}"]) for i in range(1, 5)] for row in rows]).mean(axis=1)
    steps = np.diff(stamps)
    moving = np.abs(np.diff(payout)) > MOVING * steps
    return stamps, np.concatenate([[0.0], np.cumsum(np.where(moving, steps, 0.0))])


def after_motion(bag: Path, seconds: float) -> float:
    """The stamp [s] at which the stage has moved for `seconds` since the start of the recording."""
    stamps, moved = moving_time(bag)
    return float(stamps[np.searchsorted(moved, seconds)])


def motion_between(bag: Path, start: float, end: float) -> float:
    """How long [s] the stage moved between the stamps `start` and `end`."""
    stamps, moved = moving_time(bag)
    return float(np.interp(end, stamps, moved) - np.interp(start, stamps, moved))


def parameter_lines(result: Tracked, index: int) -> str:
    """One message's tracked values as text, for the test's printout."""
    return "; ".join(f"{name} {result.values[index, k]:.6g} +- {result.sigmas[index, k]:.2g}"
                     + ("" if result.in_use[index, k] else " (not in use)") for k, name in enumerate(NAMES))

