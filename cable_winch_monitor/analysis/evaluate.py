"""The model at every row: predicted channels, residuals, noise levels and the noise-normalised score.

Solving is the cost of the whole loop. Where the model solves in batches (rope law, load
and geometry before the solve), an `Evaluator` solves all rows at once along the bag;
otherwise row by row, each from the row before. It reuses the solutions outright when
only measurement effects changed (`solutions` is keyed on everything that affects a solve).

An evaluation is a function of the model and the rows alone, never of what was evaluated
before: a rigid rope's taut set, or the pulleys' fixed point, is a local optimum, so a
start carried over from another model would keep that model's choice. Every estimate
starts from one fixed place: the cold estimate of the evaluator's `reference` model (a
fit's base: its parameters stay close, so a few Newton steps reach the optimum), or, without
a reference, the model's own cold estimate.

Where the plant file gives the encoders a noise (`noise.length`), the lengths are
measurements too (errors in variables): each row is the fused estimate of its lengths
and the channels measured at it (effects.estimate), and the length corrections count in
the score in units of their sigma. A row's cost, its squared corrections and residuals,
is spread over the channels it measured, so that a model explaining the data down to the
noise scores 1 as before.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bagio.reader import BagError
from ..effects import PlantModel
from ..effects.estimate import estimate_recording, fuses
from ..model.estimator import Estimate
from ..model.statics.result import Solution
from .data import Dataset

FAILED_PENALTY = 30.0  # [sigma] residual of a measured channel whose row the model cannot solve
BLOCKS = 20            # the bag is cut into this many blocks in time for the train / held-out split
HELD_OUT = (2, 5, 8)   # block k is held out when k % 10 is one of these: 30 %, spread over the whole bag
MIN_BLOCK = 10.0       # [s] shortest block: longer than the winch drift's correlation over neighbours


class Evaluator:
    """Solutions and predictions for the rows of a dataset under any model, each a function of the model
    alone (see the module): estimates start from the `reference` model's cold estimate, or cold."""

    def __init__(self, data: Dataset, reference: PlantModel | None = None):
        self.data = data
        self.conditions = data.conditions()
        self.reference = reference
        self._starts: list[Estimate] | None = None
        self._cached: tuple[tuple, list[Solution]] | None = None
        self._estimated: tuple[tuple, list[Estimate]] | None = None
        self.solves = 0

    def _estimate(self, model: PlantModel, starts: list[Estimate] | None) -> list[Estimate]:
        measured = {name: self.data.measured[:, c] for c, name in enumerate(self.data.channels)}
        out = estimate_recording(model, self.data.lengths, measured, self.conditions, starts) if len(self.data) else []
        self.solves += len(out)
        return out

    def estimates(self, model: PlantModel) -> list[Estimate] | None:
        """The fused estimate of every row from its lengths and measured channels (None: the model takes
        the lengths as exact), started from the reference's cold estimate. Measurement effects change an
        estimate too: keyed on every effect."""
        if not fuses(model):
            return None
        key = (model.solve_key(), tuple((e.name, tuple(e.values.items())) for e in model.effects))
        if self._estimated is not None and self._estimated[0] == key:
            return self._estimated[1]
        if self._starts is None and self.reference is not None and fuses(self.reference):
            self._starts = self._estimate(self.reference, None)
        out = self._estimate(model, self._starts)
        self._estimated = (key, out)
        return out

    def corrections(self, model: PlantModel) -> np.ndarray | None:
        """(rows, 4) length corrections in sigma of the encoders (None: the lengths taken as exact)."""
        estimates = self.estimates(model)
        if estimates is None:
            return None
        return np.array([e.corrections_sigma if e.fused else np.zeros(4) for e in estimates]).reshape(-1, 4)

    def normalised(self, model: PlantModel, noise: np.ndarray) -> np.ndarray:
        """The model's residuals and length corrections in sigma (see `normalised`)."""
        return normalised(self.residuals(model), self.data.measured, noise, self.corrections(model))

    def score(self, model: PlantModel, noise: np.ndarray) -> float:
        """The model's noise-normalised score on these rows (see `score`)."""
        return score(self.residuals(model), self.data.measured, noise, self.corrections(model))

    def solutions(self, model: PlantModel) -> list[Solution]:
        estimates = self.estimates(model)
        if estimates is not None:
            return [e.solution for e in estimates]
        key = model.solve_key()
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1]
        out = self._batched(model) if model.batchable else self._row_by_row(model)
        for k in range(len(out) - 2, -1, -1):  # a failed cold start may succeed from the next row's solution
            if not out[k].ok and out[k + 1].ok:
                out[k] = model.solve(self.data.lengths[k], out[k + 1], self.conditions[k])
        self._cached = (key, out)
        return out

    def _batched(self, model: PlantModel) -> list[Solution]:
        """All rows at once, along the bag (`PlantModel.solve_batch`); rows it cannot solve, again cold."""
        out = model.solve_batch(self.data.lengths, self.conditions)
        self.solves += len(out)
        for k in [k for k, solution in enumerate(out) if not solution.ok]:
            out[k] = model.solve(self.data.lengths[k], None, self.conditions[k])
            self.solves += 1
        return out

    def _row_by_row(self, model: PlantModel) -> list[Solution]:
        """Each row from the row before's solution: pose-dependent geometry."""
        out: list[Solution] = []
        previous: Solution | None = None
        for k, lengths in enumerate(self.data.lengths):
            solution = model.solve(lengths, previous, self.conditions[k])
            if not solution.ok and previous is not None:  # a warm start across a kink can fail: retry cold
                solution = model.solve(lengths, None, self.conditions[k])
            self.solves += 1
            previous = solution if solution.ok else previous
            out.append(solution)
        return out

    def predicted(self, model: PlantModel) -> np.ndarray:
        """(rows, channels) of what the model says each sensor reads (NaN where the solve failed)."""
        names = self.data.channels
        out = np.full((len(self.data), len(names)), np.nan)
        for k, (solution, conditions) in enumerate(zip(self.solutions(model), self.conditions)):
            if solution.ok:
                predicted = model.predict(solution, conditions)
                out[k] = [predicted[c] for c in names]
        return out

    def residuals(self, model: PlantModel) -> np.ndarray:
        """Measured minus predicted (NaN where not measured)."""
        return self.data.measured - self.predicted(model)


def _normalised(residuals: np.ndarray, measured: np.ndarray, noise: np.ndarray) -> np.ndarray:
    z = residuals / noise
    return np.where(np.isfinite(measured) & ~np.isfinite(z), FAILED_PENALTY, z)


def normalised(residuals: np.ndarray, measured: np.ndarray, noise: np.ndarray,
               corrections: np.ndarray | None = None) -> np.ndarray:
    """Residuals in units of sensor noise, flattened over measured values, then the length corrections
    [sigma] of the rows (errors in variables); unsolvable rows count as a FAILED_PENALTY-sigma miss (so
    a fit cannot improve by making rows unsolvable)."""
    z = _normalised(residuals, measured, noise)[np.isfinite(measured)]
    return z if corrections is None else np.concatenate([z, corrections.reshape(-1)])


def score(residuals: np.ndarray, measured: np.ndarray, noise: np.ndarray,
          corrections: np.ndarray | None = None) -> float:
    """Noise-normalised RMS error: the root of the mean over measured channels of each channel's mean
    squared normalised error (1.0: the model explains the data down to the sensor noise). With the
    rows' length corrections [sigma], each row's squared corrections are shared among the channels it
    measured (a row's cost is chi-square with as many degrees of freedom as it measured channels)."""
    z2 = _normalised(residuals, measured, noise) ** 2
    seen = np.isfinite(measured)
    if corrections is not None:
        per_row = np.sum(corrections ** 2, axis=1) / np.maximum(seen.sum(axis=1), 1)
        z2 = z2 + per_row[:, None]
    per_channel = [np.mean(z2[seen[:, c], c]) for c in range(measured.shape[1]) if seen[:, c].any()]
    return float(np.sqrt(np.mean(per_channel))) if per_channel else float("nan")


@dataclass(frozen=True)
class ChannelStats:
    rms: float
    max_abs: float
    noise: float
    score: float
    count: int
    failed: int

    def to_dict(self) -> dict[str, float]:
        return {"rms": self.rms, "max_abs": self.max_abs, "noise": self.noise, "score": self.score,
                "count": self.count, "unsolved": self.failed}


def channel_stats(residuals: np.ndarray, measured: np.ndarray, noise: np.ndarray,
                  names: tuple[str, ...]) -> dict[str, ChannelStats]:
    """RMS, largest error and noise-normalised RMS of every measured channel (columns named `names`)."""
    out = {}
    for c, name in enumerate(names):
        seen = np.isfinite(measured[:, c])
        if not seen.any():
            continue
        values = residuals[seen, c]
        ok = values[np.isfinite(values)]
        rms = float(np.sqrt(np.mean(ok ** 2))) if ok.size else float("nan")
        out[name] = ChannelStats(rms, float(np.abs(ok).max()) if ok.size else float("nan"), float(noise[c]),
                                 score(residuals[:, [c]], measured[:, [c]], noise[[c]]), int(seen.sum()),
                                 int(seen.sum() - ok.size))
    return out


def noise(model: PlantModel, data: Dataset) -> tuple[np.ndarray, dict[str, str]]:
    """1-sigma noise of each channel and where it came from: the model's plant file's `noise:` section, or an
    estimate from the data (second differences of consecutive samples, robust: 1.4826 MAD / sqrt 6)."""
    sigma, source = np.full(len(data.channels), np.nan), {}
    for c, name in enumerate(data.channels):
        value = model.plant.noise.get(model.channels.get(name).noise_key, np.nan)
        if np.isfinite(value) and value > 0.0:
            sigma[c], source[name] = value, "plant file"
            continue
        series = data.measured[np.isfinite(data.measured[:, c]), c]
        if series.size >= 5:
            second = np.diff(series, 2)
            sigma[c] = max(1.4826 * np.median(np.abs(second - np.median(second))) / np.sqrt(6.0), 1e-12)
            source[name] = "estimated from the data"
    return sigma, source


def split(data: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Training and held-out rows: interleaved blocks in time (see HELD_OUT); BagError where the bag is too
    short to hold a held-out block (the first is the third block of at least MIN_BLOCK seconds)."""
    span = data.times[-1] - data.times[0] if len(data) else 0.0
    length = max(span / BLOCKS, MIN_BLOCK)
    block = np.floor((data.times - data.times[0]) / length).astype(int) if len(data) else np.zeros(0, int)
    held = np.isin(block % 10, HELD_OUT)
    if not held.any():
        raise BagError(f"{data.bag}: its measurements span {span:.1f} s, too short to hold data out: training and "
                       f"held-out rows are interleaved blocks of at least {MIN_BLOCK:g} s, so a bag needs more than "
                       f"{min(HELD_OUT) * MIN_BLOCK:g} s")
    return np.flatnonzero(~held), np.flatnonzero(held)


def thin(rows: np.ndarray, kinds: np.ndarray, per_kind: int) -> np.ndarray:
    """At most `per_kind` rows of each kind (winches, each sensor topic), evenly spread in time."""
    kept = []
    for kind in np.unique(kinds[rows]):
        mine = rows[kinds[rows] == kind]
        if mine.size > per_kind:
            mine = mine[np.linspace(0, mine.size - 1, per_kind).round().astype(int)]
        kept.append(mine)
    return np.sort(np.concatenate(kept))
