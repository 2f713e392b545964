"""Where a channel's prediction cannot be determined from the lengths: its sensitivity to a millimetre.

Four taut ropes hold a platform with six degrees of freedom by four lengths: where the
ropes are nearly stiff against the internal mode (-1, 1, -1, 1) -- lengthening one diagonal
pair and shortening the other -- a millimetre of encoder error moves the tensions by
kilonewtons. Errors of such a channel there say little about the model. For a thinned
set of rows the change of every prediction is taken for a step of LENGTH_STEP along the
internal mode (each way) and on each cable (forward differences, d(prediction)/d(length)); a
channel is ill-conditioned where the internal mode, or the
worst mode of a millimetre per cable, moves its prediction by more than LIMIT noise levels
per millimetre (encoders are good to about a millimetre). The spans in time where that
holds are reported.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..effects import PlantModel
from ..model.conditions import Conditions
from ..model.statics.result import Solution
from .data import Dataset
from .evaluate import thin

LENGTH_STEP = 1.0e-3                         # [m] one millimetre of encoder error
INTERNAL_MODE = np.array([-1.0, 1.0, -1.0, 1.0])
ROWS = 120                                    # winch rows examined (the cost is 6 solves each) ...
ROWS_SOLVED_ONE_BY_ONE = 40                   # ... where the geometry depends on the pose (pulleys): no batches
LIMIT = 3.0  # [sigma per mm] beyond this one millimetre of encoder error alone misses by compare's 3 sigma


MAX_SPANS = 8                                 # spans listed per channel


@dataclass(frozen=True)
class IllConditioned:
    """`channel` moves by up to `sigma_per_mm` noise levels per mm along `mode` in the time `spans` [s from the
    start of the recording]."""

    channel: str
    mode: str
    sigma_per_mm: float
    spans: tuple[tuple[float, float], ...]

    def describe(self) -> str:
        where = ", ".join(f"{a:.1f}" if b - a < 0.05 else f"{a:.1f}-{b:.1f}" for a, b in self.spans[:MAX_SPANS])
        more = f" and {len(self.spans) - MAX_SPANS} more" if len(self.spans) > MAX_SPANS else ""
        return (f"{self.channel} moves up to {self.sigma_per_mm:.3g} sigma per mm of length along {self.mode} "
                f"at {where}{more} s: the lengths do not determine its prediction there")

    def to_dict(self) -> dict[str, Any]:
        return {"channel": self.channel, "mode": self.mode, "sigma_per_mm": self.sigma_per_mm,
                "spans": [list(span) for span in self.spans], "description": self.describe()}


def _changes(model: PlantModel, data: Dataset, rows: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(rows, steps, channels): how far each prediction of the forward kinematics moves for each length
    step (NaN where unsolved), the rows solved together per step (`PlantModel.solve_batch`)."""
    subset = data.subset(rows)
    conditions = subset.conditions()
    before = _predictions(model, model.solve_batch(subset.lengths, conditions), conditions, data.channels)
    out = np.full((len(rows), len(steps), len(data.channels)), np.nan)
    for s, step in enumerate(steps):
        moved = model.solve_batch(subset.lengths + step, conditions)
        out[:, s] = _predictions(model, moved, conditions, data.channels) - before
    return out


def _predictions(model: PlantModel, solutions: list[Solution], conditions: list[Conditions],
                 names: tuple[str, ...]) -> np.ndarray:
    """What each channel `names` reads at each solution (n, channels), NaN rows where not solved."""
    predicted = model.predict_solutions(solutions, conditions)
    return np.column_stack([predicted[c] for c in names]) if names else np.zeros((len(solutions), 0))


def ill_conditioned(model: PlantModel, data: Dataset, noise: np.ndarray) -> list[IllConditioned]:
    """Spans where a channel's prediction moves more than LIMIT noise levels per millimetre of length:
    along the internal mode (a step each way: a kink where the taut set changes counts), else along
    its worst mode (the gradient from a step on each cable)."""
    winch = thin(np.flatnonzero(data.kinds == 0), data.kinds, ROWS if model.batchable else ROWS_SOLVED_ONE_BY_ONE)
    if winch.size == 0:
        return []
    steps = LENGTH_STEP * np.vstack([INTERNAL_MODE, -INTERNAL_MODE, np.eye(4)])
    change = _changes(model, data, winch, steps) / noise  # sigma per mm
    internal = np.fmax(np.abs(change[:, 0]), np.abs(change[:, 1]))
    worst = np.linalg.norm(change[:, 2:], axis=1) * 2.0  # the worst mode of 1 mm per cable has norm 2 mm
    times = data.times[winch] - data.times[0]  # from the start of the recording, as every report says
    gap = 3.0 * float(np.median(np.diff(times))) if times.size > 1 else 1.0
    out = []
    for c, name in enumerate(data.channels):
        for label, size in (("the internal mode (-1, 1, -1, 1)", internal[:, c]), ("its worst mode", worst[:, c])):
            spans = _spans(np.nan_to_num(size) > LIMIT, times, gap)
            if spans:  # the internal mode first: where it explains the channel, the worst mode adds nothing
                out.append(IllConditioned(name, label, float(np.nanmax(size)), spans))  # some row exceeds: not all NaN
                break
    return sorted(out, key=lambda s: -s.sigma_per_mm)


def _spans(hit: np.ndarray, times: np.ndarray, gap: float) -> tuple[tuple[float, float], ...]:
    """(start, end) of the runs of `hit` rows, rows closer than `gap` in time joined."""
    rows = np.flatnonzero(hit)
    if rows.size == 0:
        return ()
    breaks = np.flatnonzero(np.diff(times[rows]) > gap)
    starts, ends = np.r_[0, breaks + 1], np.r_[breaks, rows.size - 1]
    return tuple((float(times[rows[a]]), float(times[rows[b]])) for a, b in zip(starts, ends))
