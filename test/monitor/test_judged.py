"""A run of samples judged as columns: each sample's outputs and outcome read off the same row, and runs put
together are the samples of each, in order -- taut, slack and single-cable samples, estimated or taken as exact."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cable_winch_monitor.model.statics.result import SolveStatus
from cable_winch_monitor.monitor.judged import Judged
from cable_winch_monitor.monitor.pipeline import CompleteSample, MonitorPipeline

NAN = float("nan")


def samples(count: int) -> list[CompleteSample]:
    """A lowering at 0.4 m/s, winches at 10 Hz, with a rope paid out 0.3 m too far in the middle (slack) and a
    sample hanging from one rope (the others 30 m longer), a load pin on the first rope."""
    out = []
    for k in range(count):
        lengths = np.full(4, 60.0 + 0.04 * k) + np.array([0.0, 0.002, -0.001, 0.001])
        if count // 3 <= k < count // 2:
            lengths[1] += 0.3
        if k == count - 2:
            lengths[1:] += 30.0
        out.append(CompleteSample(100.0 + k / 10, lengths, [0, 1, 2, 3], [3.0e4, NAN, NAN, NAN], [0.4] * 4,
                                  {"tension_cable_1": 3.0e4}, {}, {}))
    return out


@pytest.mark.parametrize("estimated", [True, False])
def test_each_samples_outcome_is_its_outputs_and_runs_put_together_keep_them(plant, estimated):
    noise = {**plant.noise, "length": 1e-3} if estimated else {k: v for k, v in plant.noise.items() if k != "length"}
    monitor = MonitorPipeline(plant.with_changes(noise=noise))
    run = samples(40)
    judged = monitor.judge_samples(run, monitor.solve_samples(run, monitor.conditions(run)))
    statuses = {output.solution.status for output in judged.outputs()}
    assert {SolveStatus.SOLVED, SolveStatus.SINGLE_CABLE_INDETERMINATE} <= statuses
    assert any("slack: cable_2 loose by" in output.alarm.reason for output in judged.outputs())
    assert (judged.solved.views is not None) == estimated
    for k, (output, outcome) in enumerate(zip(judged.outputs(), judged.outcomes())):
        solution = output.solution
        assert outcome.stamp == output.stamp == run[k].stamp
        assert (outcome.status, outcome.tension_state, outcome.failure) == (solution.status, solution.tension_state,
                                                                            solution.failure)
        assert outcome.level == output.alarm.level.name and outcome.residuals == output.residuals
        assert outcome.basis == (output.basis.summary if output.basis is not None else "")
        if solution.ok:  # what every channel reads of the state: the load pins are the tensions (weightless ropes)
            assert outcome.predicted is not None and output.residuals is not None
            assert [outcome.predicted[f"tension_cable_{i + 1}"] for i in range(4)] == solution.tensions.tolist()
            assert output.residuals.channels == ("tension_cable_1",) and output.residuals.measured == (3.0e4,)
        else:
            assert outcome.predicted is None and output.residuals is None
        if estimated:
            view = output.model
            assert view is not None and outcome.error == (tuple(view.length_error), tuple(view.pin_error))
            assert dict(outcome.faults) == dict(view.faults)
        else:
            assert output.model is None and outcome.error is None and outcome.faults == {}
    halves = [monitor.judge_samples(part, monitor.solve_samples(part, monitor.conditions(part)))
              for part in (run[:17], run[17:])]
    together = Judged.concatenated(halves)
    assert len(together) == len(run) and together.stamps == [s.stamp for s in run]
    assert together.outcomes().each() == halves[0].outcomes().each() + halves[1].outcomes().each()
    for k, output in enumerate(together.outputs()):
        part, row = (halves[0], k) if k < 17 else (halves[1], k - 17)
        alone = part.output(row)
        assert output.solution is alone.solution and output.alarm.reason == alone.alarm.reason
        assert np.array_equal(output.alarm.sync_errors, alone.alarm.sync_errors)
        assert (output.model is None) == (alone.model is None)
        if output.model is not None and alone.model is not None:
            assert np.array_equal(output.model.length_error, alone.model.length_error)
            assert math.isclose(output.model.tilt_sigma, alone.model.tilt_sigma)


def test_a_run_of_no_sample(plant):
    monitor = MonitorPipeline(plant.with_changes(noise={**plant.noise, "length": 1e-3}))
    judged = monitor.judge_samples([], monitor.solve_samples([], []))
    assert len(judged) == 0 and judged.outputs() == [] and judged.outcomes().each() == []
    assert len(Judged.concatenated([])) == 0 and monitor.last is None
