"""A run of samples' outputs encoded together from its columns are, message by message, what `fields` lays out
for each sample alone and rosbags serialises: taut, slack, single-cable and unsolved states; fused and unfused
estimates; estimated runs and runs of lengths taken as exact; sensors rejected and left out; an alarm without a
clearance; texts with characters of more than one byte."""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.channels import BUILTIN_CHANNELS
from cable_winch_monitor.messages import fields, frames, outputs, records, stacked
from cable_winch_monitor.model.estimator import estimate
from cable_winch_monitor.model.solvers.energy import solve_energy
from cable_winch_monitor.monitor.alarm import AlarmPolicy, Alarms, AlarmTracker
from cable_winch_monitor.monitor.basis import Basis
from cable_winch_monitor.monitor.clearance import solution_clearance
from cable_winch_monitor.monitor.judged import Judged, ModelViews, SolvedRun
from cable_winch_monitor.monitor.residuals import Residuals

LENGTHS = [[80.0] * 4, [100.0, 100.0, 100.0, 100.5], [20.0, 21.0, 22.0, 21.5], [np.nan, 80.0, 80.0, 80.0],
           [300.0, 300.02, 300.0, 299.98], [80.0] * 4, [80.0] * 4]
TEXTS = ["tilt measured; the model agrees", "", "the model's: 0.213 m closer at deck_3/p7 than the measured tilt gives",
         "model only (no tilt measured)", "tilt measured; the model disagrees by +0.210 m at deck_1/p3 (± 3σ)", "é",
         "TILT MEASURED; THE MODEL AGREES"]  # as long as the first: encoded with it, each its own text
SENSORS = [((), ()), (("/platform/imu",), ()), ((), ("tension_cable_2", "/platform/position")), ((), ()),
           (("/platform/imu", "/platform/depth"), ("tension_cable_4",)), ((), ("é",)), ((), ())]


def serialised(topic: str, values: dict[str, Any]) -> bytes:
    msgtype = outputs.OUTPUT_TYPES[topic]
    return bytes(typestore().serialize_cdr(records.build(msgtype, values), msgtype))


def judged_run(plant: Any, estimated: bool) -> Judged:
    """A run of odd samples, with the model's view of each where `estimated` (a plant that fuses: every sample's)."""
    count = len(LENGTHS)
    solutions = [solve_energy(plant, lengths) for lengths in LENGTHS]
    clearances = [solution_clearance(plant, solution) for solution in solutions]
    alarms = AlarmTracker(AlarmPolicy.from_plant(plant)).update_many(solutions, clearances, TEXTS)
    estimates = [estimate(plant, LENGTHS[k]) if k % 2 == 0 else None for k in range(count)]
    views = None
    if estimated:
        errors = np.random.default_rng(5).normal(size=(4, count, 4))
        views = ModelViews([clearance if k != 3 else None for k, clearance in enumerate(clearances)], *errors,
                           [1e-4] * count, [rejected for rejected, _ in SENSORS], [left_out for _, left_out in SENSORS],
                           [{} for _ in range(count)], [None] * count, [False] * count)
    return Judged([10.0 + k for k in range(count)], SolvedRun(solutions, clearances, estimates, {}, views),
                  [Basis(clearance, text) for clearance, text in zip(clearances, TEXTS)], alarms, [None] * count)


def twice(judged: Judged) -> Judged:
    """The run, then the run again."""
    alarms = judged.alarms
    return Judged(judged.stamps * 2, SolvedRun.concatenated([judged.solved] * 2), judged.bases * 2,
                  Alarms(alarms.levels * 2, alarms.clearances * 2, np.vstack([alarms.sync_errors] * 2),
                         alarms.reasons * 2), judged.residuals * 2)


@pytest.mark.parametrize("estimated", [True, False])
def test_every_message_of_a_run_is_the_one_of_its_sample_alone(plant, estimated):
    """Encoded together from the run's columns (`run_records`), a message at a time from each sample's outputs
    (`sample_records`, the node's), and each laid out by `fields` and serialised by rosbags: the same bytes."""
    judged = judged_run(plant, estimated)
    run = judged.outputs()
    statuses = {output.solution.status for output in run}
    assert len(statuses) >= 3 and any(o.estimate is not None and o.estimate.fused for o in run)
    assert any(o.alarm.clearance is None for o in run) and all((o.model is not None) == estimated for o in run)
    assert run[0].alarm.reason != run[6].alarm.reason and len(run[0].alarm.reason) == len(run[6].alarm.reason)
    stamps = [(1_700_000_000 + k, 123_456_789 * k % 1_000_000_000) for k in range(len(run))]
    together = records.run_records(stamps, judged, BUILTIN_CHANNELS)
    assert together == [records.sample_records(stamp, output, BUILTIN_CHANNELS) for stamp, output in zip(stamps, run)]
    assert len(run) * 2 >= records.STACKED_FROM  # a run that long is encoded together
    assert records.solved_records(stamps * 2, twice(judged), BUILTIN_CHANNELS) == together * 2
    for stamp, output, written in zip(stamps, run, together):
        solution = output.solution
        want = []
        if solution.ok:
            position, quaternion = solution.position.tolist(), solution.quaternion.tolist()
            want += [(outputs.POSE, fields.pose_stamped(stamp, position, quaternion)),
                     (outputs.TF, frames.platform_tf(stamp, position, quaternion))]
        want += [(outputs.TENSION, fields.tension_distribution(stamp, solution, output.estimate, BUILTIN_CHANNELS)),
                 (outputs.ALARM, fields.collision_alarm(stamp, output.alarm))]
        if output.model is not None:
            want.append((outputs.MODEL_ERROR, fields.model_error(stamp, output.model, output.estimate, output.basis.text)))
        assert [(topic, data) for topic, _, data in written] == [(topic, serialised(topic, v)) for topic, v in want]


def test_residuals_encoded_together_are_each_messages_own():
    """A window's samples' residuals (channels measured at each: pins, an inclinometer, a depth gauge, in any
    mix, NaN noise too) encoded together are the records of each one alone."""
    rng = np.random.default_rng(11)
    kinds = [("tension_cable_1", "tension_cable_2", "tension_cable_3", "tension_cable_4"), ("roll", "pitch"),
             ("depth",), ("tension_cable_2", "roll", "x")]
    residuals = []
    for k in range(40):
        channels = kinds[k % len(kinds)]
        measured, predicted = rng.normal(size=(2, len(channels))) * 10.0 ** rng.integers(-4, 5)
        noise = [np.nan if (k + i) % 7 == 0 else 0.01 for i in range(len(channels))]
        residuals.append(Residuals(float(k), channels, tuple(measured.tolist()), tuple(predicted.tolist()),
                                   tuple(noise)))
    stamps = [(1_700_000_000 + k, 987_654_321 * k % 1_000_000_000) for k in range(len(residuals))]
    together = stacked.residual_records(stamps, residuals)
    alone = [records.residual_records(stamp, r)[0] for stamp, r in zip(stamps, residuals)]
    assert together == alone
    assert [data for _, _, data in alone] == [serialised(outputs.RESIDUALS, fields.model_residuals(s, r))
                                              for s, r in zip(stamps, residuals)]
