"""What the monitor makes of samples: a run of them solved and judged together, a column per quantity, and
one sample's outputs taken from it.

The stages run over a run of consecutive samples (replay's window, the node's samples taken together; one
sample is a run of one). `MonitorPipeline.solve_samples` gives a `SolvedRun` -- each sample's equilibrium,
clearance, estimate, what every channel reads there, and the model's own view of it (`ModelViews`) --
and `judge_samples` a `Judged` run: what each alarm is based on, the alarms, each sample's load-pin
residuals. Replay's encoders read the columns (messages.records.run_records) and its counts the
`outcomes`; a sample's `MonitorOutput` is made where one sample is needed whole: the node's outputs, a
scene, /diagnostics.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..frozen import fast_init
from ..model.estimator import Estimate
from ..model.statics.result import Solution, SolveStatus
from .alarm import Alarm, Alarms
from .basis import Basis
from .clearance import Clearance
from .residuals import Residuals
from .tracking import ParameterView


@fast_init
@dataclass(frozen=True)
class ModelView:
    """What the model says of a sample beside the estimate: the clearance of its own equilibrium for the
    reported lengths, its expected error, and that error per rope."""

    clearance: Clearance | None   # of the model's own equilibrium for the reported lengths
    length_error: np.ndarray      # (4,) model minus reported rope length [m]
    length_sigma: np.ndarray      # (4,) its 1-sigma [m]
    pin_error: np.ndarray         # (4,) load-pin reading minus the model's prediction [N]
    pin_sigma: np.ndarray         # (4,) its 1-sigma [N]
    tilt_sigma: float             # [rad] 1-sigma of the tilt the model's lengths give
    rejected: tuple[str, ...]     # sensors rejected at this sample (they contradict the others)
    left_out: tuple[str, ...]     # sensors left out while they are found faulty (contradicting, stuck, silent)
    faults: Mapping[str, str] = field(default_factory=dict)  # each of those sensors: why
    parameters: ParameterView | None = None  # the tracked plant parameters (None: none tracked)
    parameters_due: bool = False  # this sample publishes them (the first of each second of stamps)


@dataclass(frozen=True)
class ModelViews:
    """The `ModelView` of each sample of a run, a column each (row k is sample k's)."""

    clearances: list[Clearance | None]
    length_error: np.ndarray      # (n, 4) [m]
    length_sigma: np.ndarray      # (n, 4) [m]
    pin_error: np.ndarray         # (n, 4) [N]
    pin_sigma: np.ndarray         # (n, 4) [N]
    tilt_sigma: list[float]       # [rad]
    rejected: list[tuple[str, ...]]
    left_out: list[tuple[str, ...]]
    faults: list[dict[str, str]]
    parameters: list[ParameterView | None]
    parameters_due: list[bool]

    def __len__(self) -> int:
        return len(self.clearances)

    def __getitem__(self, k: int) -> ModelView:
        return ModelView(self.clearances[k], self.length_error[k], self.length_sigma[k], self.pin_error[k],
                         self.pin_sigma[k], self.tilt_sigma[k], self.rejected[k], self.left_out[k], self.faults[k],
                         self.parameters[k], self.parameters_due[k])

    @classmethod
    def concatenated(cls, parts: Sequence[ModelViews]) -> ModelViews:
        """Consecutive runs' views as one run's."""
        def listed(name: str) -> list:
            return [value for part in parts for value in getattr(part, name)]

        def stacked(name: str) -> np.ndarray:
            return np.concatenate([getattr(part, name) for part in parts])

        return cls(listed("clearances"), stacked("length_error"), stacked("length_sigma"), stacked("pin_error"),
                   stacked("pin_sigma"), listed("tilt_sigma"), listed("rejected"), listed("left_out"), listed("faults"),
                   listed("parameters"), listed("parameters_due"))


@dataclass(frozen=True)
class SolvedRun:
    """Consecutive samples estimated (or solved) together: each one's equilibrium, wall clearance, fused
    estimate (None: the lengths taken as exact), what every channel reads there (NaN where not solved),
    and the model's own view of it (fused plants; None: the lengths taken as exact)."""

    solutions: list[Solution]
    clearances: list[Clearance | None]
    estimates: list[Estimate | None]
    predicted: dict[str, np.ndarray]  # channel -> (n,)
    views: ModelViews | None = None

    def __len__(self) -> int:
        return len(self.solutions)

    @classmethod
    def concatenated(cls, parts: Sequence[SolvedRun]) -> SolvedRun:
        """Consecutive runs as one (each estimator's window, say, a part; none: a run of no sample)."""
        if len(parts) <= 1:
            return parts[0] if parts else cls([], [], [], {})
        names = dict.fromkeys(name for part in parts for name in part.predicted)
        predicted = {name: np.concatenate([part.predicted.get(name, np.full(len(part), np.nan)) for part in parts])
                     for name in names}
        views = [part.views for part in parts if part.views is not None]
        return cls([solution for part in parts for solution in part.solutions],
                   [clearance for part in parts for clearance in part.clearances],
                   [estimate for part in parts for estimate in part.estimates], predicted,
                   ModelViews.concatenated(views) if len(views) == len(parts) else None)


@fast_init
@dataclass(frozen=True)
class MonitorOutput:
    """Everything the monitor publishes for one solved sample, stamped with its input stamp."""

    stamp: float
    solution: Solution
    clearance: Clearance | None
    alarm: Alarm
    residuals: Residuals | None
    estimate: Estimate | None = None  # the fused estimate the solution is (None: the lengths taken as exact)
    model: ModelView | None = None    # the model's own clearance and error (None: the lengths taken as exact)
    basis: Basis | None = None        # what the alarm is based on

    @property
    def refused(self) -> tuple[str, ...]:
        """The sensors not fused at this sample because they contradict the others."""
        return () if self.model is None else tuple(sorted(set(self.model.rejected) | set(self.model.left_out)))


class Outcome(NamedTuple):
    """What a solved sample leaves behind for the counts, /diagnostics and the residuals of the sensor
    messages after it: small, so that replay's second process sends it back cheaply."""

    stamp: float
    status: SolveStatus
    tension_state: str
    level: str
    faults: Mapping[str, str]             # sensors left out at the sample, with why
    predicted: dict[str, float] | None    # what every channel reads of its state (None: not solved)
    residuals: Residuals | None
    failure: str = ""                     # why it was not solved
    basis: str = ""                       # what the alarm is based on, without numbers ("": the lengths taken as exact)
    error: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # the model's length [m] and load-pin [N] error per rope


@dataclass(frozen=True)
class Outcomes:
    """What the samples of a judged run leave behind, a column each (`each()[k]` is sample k's `Outcome`): what
    replay's second process hands back, a few lists and arrays rather than a tuple and a dict per sample."""

    stamps: list[float]
    statuses: list[SolveStatus]
    tension_states: list[str]
    levels: list[str]
    faults: Sequence[Mapping[str, str]]
    channels: list[str]              # the channels predicted
    predicted: np.ndarray            # (n, len(channels)) what each reads of each sample's state (unused where not solved)
    residuals: list[Residuals | None]
    failures: list[str]
    bases: list[str]
    length_error: np.ndarray | None  # (n, 4) [m] the model's (None: the lengths taken as exact)
    pin_error: np.ndarray | None     # (n, 4) [N]

    def __len__(self) -> int:
        return len(self.stamps)

    def __iter__(self) -> Iterator[Outcome]:
        return iter(self.each())

    def each(self) -> list[Outcome]:
        """Each sample's `Outcome`."""
        names, count = self.channels, len(self)
        errors: list[tuple[tuple[float, ...], tuple[float, ...]] | None] = [None] * count
        if self.length_error is not None and self.pin_error is not None:
            errors = list(zip(map(tuple, self.length_error.tolist()), map(tuple, self.pin_error.tolist())))
        return [Outcome(stamp, status, state, level, faults, dict(zip(names, row)) if status is SolveStatus.SOLVED
                        else None, residuals, failure, basis, error)
                for stamp, status, state, level, faults, row, residuals, failure, basis, error in zip(
                    self.stamps, self.statuses, self.tension_states, self.levels, self.faults, self.predicted.tolist(),
                    self.residuals, self.failures, self.bases, errors)]


@dataclass(frozen=True)
class Judged:
    """A run of samples judged: their `SolvedRun`, what each alarm is based on, the alarms, and each
    sample's load-pin residuals (None where it has none)."""

    stamps: list[float]
    solved: SolvedRun
    bases: list[Basis]
    alarms: Alarms
    residuals: list[Residuals | None]

    def __len__(self) -> int:
        return len(self.stamps)

    @classmethod
    def concatenated(cls, parts: Sequence[Judged]) -> Judged:
        """Consecutive runs as one (samples judged one at a time, say, to be encoded together)."""
        if len(parts) == 1:
            return parts[0]
        if not parts:
            return cls([], SolvedRun.concatenated([]), [], Alarms.concatenated([]), [])
        return cls([stamp for part in parts for stamp in part.stamps],
                   SolvedRun.concatenated([part.solved for part in parts]),
                   [basis for part in parts for basis in part.bases],
                   Alarms.concatenated([part.alarms for part in parts]),
                   [residuals for part in parts for residuals in part.residuals])

    def output(self, k: int) -> MonitorOutput:
        """Sample k's outputs."""
        solved = self.solved
        return MonitorOutput(self.stamps[k], solved.solutions[k], solved.clearances[k], self.alarms[k],
                             self.residuals[k], solved.estimates[k], None if solved.views is None else solved.views[k],
                             self.bases[k])

    def outputs(self) -> list[MonitorOutput]:
        return [self.output(k) for k in range(len(self))]

    def outcomes(self) -> Outcomes:
        """What each sample leaves behind for the counts (`MonitorPipeline.note`)."""
        solved, views, count = self.solved, self.solved.views, len(self)
        solutions = solved.solutions
        names = list(solved.predicted)
        table = np.column_stack([solved.predicted[name] for name in names]) if names else np.empty((count, 0))
        return Outcomes(self.stamps, [s.status for s in solutions], [s.tension_state for s in solutions],
                        [level.name for level in self.alarms.levels],
                        [{} for _ in range(count)] if views is None else views.faults, names, table, self.residuals,
                        [s.failure for s in solutions], [basis.summary for basis in self.bases],
                        None if views is None else views.length_error, None if views is None else views.pin_error)
