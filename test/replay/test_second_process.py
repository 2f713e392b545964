"""What crosses between replay and its second process comes back as it went: samples, outcomes, residuals."""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.model.statics.result import SolveStatus
from cable_winch_monitor.monitor.judged import Outcome, Outcomes
from cable_winch_monitor.monitor.pipeline import CompleteSample
from cable_winch_monitor.monitor.residuals import Residuals
from cable_winch_monitor.replay.second_process import (
    _encoded,
    _packed,
    _plain,
    _unpacked,
)
from cable_winch_monitor.replay.stages import Staged


def test_a_windows_samples_cross_with_their_lengths_and_readings() -> None:
    samples = [CompleteSample(10.0 + k, np.array([50.0, 50.1, 50.2, 50.3]) + k, [0, 1, 2, 3], [3e4, 2.9e4, float("nan"), 3.1e4],
                              [0.5] * 4, {"roll": 0.001 * k}, {"roll": 9.97 + k}, {"/platform/imu": "silent"} if k else {})
               for k in range(3)]
    back = _unpacked(_packed(samples))
    assert [type(s) for s in back] == [CompleteSample] * 3
    for sent, got in zip(samples, back):
        assert np.array_equal(sent.lengths, got.lengths) and got.lengths.dtype == np.float64
        assert repr(sent._replace(lengths=None)) == repr(got._replace(lengths=None))
    assert _unpacked(_packed([])) == []


def test_a_windows_outcomes_cross_as_columns_and_come_back_as_each_samples() -> None:
    """A window's outcomes cross as columns (their residuals apart) and come back as each sample's `Outcome`: its
    predictions where solved, its residuals where it has them, the model's error per rope."""
    residuals = Residuals(10.0, ("roll", "pitch"), (0.01, 0.02), (0.011, 0.019), (1.7e-4, 1.7e-4))
    outcomes = Outcomes([10.0, 10.1], [SolveStatus.SOLVED, SolveStatus.NO_EQUILIBRIUM],
                        ["taut {1,2,3,4}", "no equilibrium"], ["OK", "WARNING"], [{}, {"/platform/imu": "silent for 1.2 s"}],
                        ["roll", "pitch"], np.array([[0.011, 0.019], [np.nan, np.nan]]), [residuals, None],
                        ["", "no equilibrium"], ["tilt measured; the model agrees", "model only"], np.zeros((2, 4)),
                        np.ones((2, 4)))
    staged = Staged([[("/platform/pose", "geometry_msgs/msg/PoseStamped", b"\x00\x01")], []], outcomes, [None, None],
                    [None, None])
    back = _encoded(_plain(staged))
    assert back == staged.encoded() and [type(e.outcome) for e in back] == [Outcome, Outcome]
    first, second = (e.outcome for e in back)
    assert type(first.residuals) is Residuals and first.residuals == residuals and second.residuals is None
    assert first.predicted == {"roll": 0.011, "pitch": 0.019} and second.predicted is None
    assert first.error == ((0.0,) * 4, (1.0,) * 4) and second.faults == {"/platform/imu": "silent for 1.2 s"}
    assert first.failure == "" and second.failure == "no equilibrium" and second.level == "WARNING"
    nothing = Outcomes([], [], [], [], [], [], np.empty((0, 0)), [], [], [], None, None)
    assert _encoded(_plain(Staged([], nothing, [], []))) == []
