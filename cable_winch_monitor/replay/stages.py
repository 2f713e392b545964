"""What becomes of a window's merged samples: estimated (or solved) together, judged one by one, encoded.

What happens to a complete sample after it is merged -- its estimate (the model's error
carried from window to window), its alarm and residuals, its records and scene -- is a
function of the merged samples in order (`WindowStages`), by the monitor's own code, which
the node runs one sample at a time. What comes out per sample is bytes and a small outcome
(`Encoded`), so that a second process can hand it back cheaply (second_process.py).
"""
from __future__ import annotations

import math
import pickle
from collections.abc import Sequence
from typing import NamedTuple

from ..messages import records
from ..messages.fields import Stamp
from ..messages.records import Record
from ..messages.scene import SceneBuilder, SceneThrottle
from ..model.conditions import Conditions
from ..monitor.diagnostics import SampleView, sample_view
from ..monitor.pipeline import CompleteSample, MonitorOutput, MonitorPipeline, Outcome


class Encoded(NamedTuple):
    """A complete sample as replay writes it: its records (outputs, and a scene where one is due), what its
    counts and the residuals of the sensor messages after it need, and at the first sample of each
    second of stamps what /diagnostics says of it."""

    records: list[Record]
    outcome: Outcome
    view: SampleView | None
    output: MonitorOutput | None = None  # the sample's outputs themselves, where encoded in this process


class WindowStages:
    """A window's merged samples estimated (or solved) together, judged one by one in order -- alarm,
    residuals, what the alarm is based on -- and encoded, by the monitor's own code."""

    def __init__(self, monitor: MonitorPipeline, scene_rate: float):
        self.monitor = monitor
        self.builder, self.throttle = SceneBuilder(monitor.plant), SceneThrottle(scene_rate)
        self.second = -math.inf  # the second of stamps whose diagnostics view was sent

    def run(self, samples: Sequence[CompleteSample], conditions: Sequence[Conditions],
            headers: Sequence[Stamp], batched: bool = True, outputs: bool = True) -> list[Encoded]:
        """What replay writes for each sample (header stamps `headers`); solved together where `batched`; with
        the outputs themselves where `outputs` (a second process sends back only what replay writes)."""
        monitor = self.monitor
        solved = monitor.solve_samples(samples, conditions) if batched else [None] * len(samples)
        out = []
        for sample, at, header, done in zip(samples, conditions, headers, solved):
            output, outcome = monitor.judge(sample, done, at)
            encoded = records.output_records(header, output)
            if self.throttle.due(output.stamp):
                encoded += records.scene_records(header, self.builder, output.solution, output.alarm)
            second = math.floor(output.stamp)
            view = None
            if second != self.second:
                self.second, view = second, sample_view(output, monitor.fusing)
            out.append(Encoded(encoded, outcome, view, output if outputs else None))
        return out

    def state(self) -> bytes:
        """What the stages have learnt so far (the estimator's, the alarm's, the scenes'), pickled."""
        monitor = self.monitor
        return pickle.dumps((monitor.estimator, monitor.alarms.level, monitor.tracker, self.throttle.last,
                             self.second), protocol=pickle.HIGHEST_PROTOCOL)

    def restore(self, state: bytes) -> None:
        monitor = self.monitor
        estimator, level, tracker, scene, self.second = pickle.loads(state)
        if estimator is not None:
            estimator.attach(monitor.model)
        monitor.estimator, monitor.alarms.level, monitor.tracker, self.throttle.last = estimator, level, tracker, scene
