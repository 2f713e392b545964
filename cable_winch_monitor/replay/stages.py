"""What becomes of a window's merged samples: estimated (or solved), judged and encoded together.

What happens to a complete sample after it is merged -- its conditions (speeds, accelerations,
directions), its estimate (the model's error carried from window to window), its alarm and
residuals, its records and scene -- is a function of the merged samples in order
(`WindowStages`), by the monitor's own code, which the node runs on the samples waiting when its
worker takes them. What comes out is columns over the window (`Staged`): each sample's bytes, the
outcomes (monitor.judged.Outcomes), the /diagnostics views and scenes due, so that a second
process can hand them back cheaply (second_process.py); `Staged.encoded` makes each sample's
`Encoded` where the replay writes. A sample due a
scene brings what the scene shows (its solution and alarm) instead of the scene itself, and its
residuals come in its outcome, not encoded: the scene is drawn and the residuals encoded where the
replay writes (`finished`), by the process that reads and writes, which has time to spare while the
second one estimates, together with the residuals of the window's sensor messages (`Measured`).
"""
from __future__ import annotations

import pickle
from collections.abc import Mapping, Sequence
from typing import NamedTuple

from ..messages import records
from ..messages.fields import Stamp
from ..messages.records import Record
from ..messages.scene import SceneBuilder, SceneState, SceneThrottle
from ..monitor.diagnostics import SampleView, sample_view
from ..monitor.judged import Judged, MonitorOutput, Outcome, Outcomes
from ..monitor.pipeline import CompleteSample, MonitorPipeline
from ..monitor.residuals import Residuals
from ..monitor.seconds import FirstOfEachSecond


class Encoded(NamedTuple):
    """A complete sample as replay writes it: its records (its outputs; once `finished`, its residuals and
    scene too), what its counts and the residuals of the sensor messages after it need, and at the first
    sample of each second of stamps what /diagnostics says of it."""

    records: list[Record]
    outcome: Outcome
    view: SampleView | None
    scene: SceneState | None = None  # where a scene is due and not drawn yet: what it shows
    output: MonitorOutput | None = None  # the sample's outputs themselves, where encoded in this process


def finished(encoded: Encoded, header: Stamp, builder: SceneBuilder, residuals: list[Record]) -> Encoded:
    """`encoded` (header stamp `header`) with its residuals' record (encoded with the window's others, where it
    has residuals) and then its scene, where one is due, after its other outputs, as the node publishes them."""
    scene = [] if encoded.scene is None else records.scene_records(header, builder, encoded.scene)
    return encoded._replace(records=encoded.records + residuals + scene, scene=None)


class Measured(NamedTuple):
    """A sensor message as replay writes it: its residuals against the model at the latest sample, and their
    record (encoded with the window's others where the replay writes)."""

    residuals: Residuals
    records: list[Record]


class Staged(NamedTuple):
    """A window's samples through the stages, a column each: their records, outcomes, /diagnostics views (None
    where none is due), the scenes due (what each shows; None where none is), and where asked for, the outputs
    themselves. `encoded` gives each sample's `Encoded`."""

    records: list[list[Record]]
    outcomes: Outcomes
    views: list[SampleView | None]
    scenes: list[SceneState | None]
    outputs: list[MonitorOutput] | None = None

    def encoded(self) -> list[Encoded]:
        outputs = self.outputs if self.outputs is not None else [None] * len(self.records)
        return [Encoded(*sample) for sample in zip(self.records, self.outcomes.each(), self.views, self.scenes, outputs)]


class WindowStages:
    """A window's merged samples estimated (or solved) together, judged in order -- alarm, residuals, what the
    alarm is based on -- and encoded, by the monitor's own code; the residuals are encoded and the scenes drawn
    (with its `builder`) where the replay writes (`finished`)."""

    def __init__(self, monitor: MonitorPipeline, scene_rate: float):
        self.monitor = monitor
        self.builder, self.throttle = SceneBuilder(monitor.plant), SceneThrottle(scene_rate)
        self.first_of_second = FirstOfEachSecond()  # where the diagnostics view of a sample is sent

    def run(self, samples: Sequence[CompleteSample], inputs: Sequence[Mapping[str, float]] | None,
            headers: Sequence[Stamp], batched: bool = True, outputs: bool = True) -> Staged:
        """What replay writes for the samples (header stamps `headers`, the extra inputs' values at their stamps
        `inputs`, None where the plant reads none); solved together where `batched`; with the outputs themselves
        where `outputs` (a second process sends back only what replay writes)."""
        monitor = self.monitor
        channels = monitor.model.channels
        conditions = monitor.conditions(samples, inputs)
        if batched:
            judged = monitor.judge_samples(samples, monitor.solve_samples(samples, conditions))
        else:  # each solved as the node solves one alone (warm-started by the one before), encoded together
            judged = Judged.concatenated([monitor.judge_samples([sample], monitor.solve_samples([sample], [at]))
                                          for sample, at in zip(samples, conditions)])
        solutions, alarms = judged.solved.solutions, judged.alarms
        scenes = [SceneState.of(solutions[k], alarms[k]) if self.throttle.due(stamp) else None
                  for k, stamp in enumerate(judged.stamps)]
        views = [sample_view(judged.output(k), monitor.fusing, channels) if self.first_of_second(stamp) else None
                 for k, stamp in enumerate(judged.stamps)]
        return Staged(records.solved_records(headers, judged, channels), judged.outcomes(), views, scenes,
                      judged.outputs() if outputs else None)

    def state(self) -> bytes:
        """What the stages have learnt so far (the estimator's, the alarm's, the scenes'), pickled."""
        monitor = self.monitor
        return pickle.dumps((monitor.estimator, monitor.alarms.level, monitor.tracker, self.throttle.last,
                             self.first_of_second), protocol=pickle.HIGHEST_PROTOCOL)

    def restore(self, state: bytes) -> None:
        monitor = self.monitor
        estimator, level, tracker, scene, self.first_of_second = pickle.loads(state)
        if estimator is not None:
            estimator.attach(monitor.model)
        monitor.estimator, monitor.alarms.level, monitor.tracker, self.throttle.last = estimator, level, tracker, scene
