"""What crosses between replay and its second process comes back as it went: samples, outcomes, residuals."""
from __future__ import annotations

import numpy as np

from cable_winch_monitor.model.statics.result import SolveStatus
from cable_winch_monitor.monitor.pipeline import CompleteSample, Outcome
from cable_winch_monitor.monitor.residuals import Residuals
from cable_winch_monitor.replay.second_process import (
    _encoded,
    _packed,
    _plain,
    _unpacked,
)
from cable_winch_monitor.replay.stages import Encoded


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


def test_an_outcome_crosses_with_its_residuals_or_without() -> None:
    residuals = Residuals(10.0, ("roll", "pitch"), (0.01, 0.02), (0.011, 0.019), (1.7e-4, 1.7e-4))
    for r in (residuals, None):
        outcome = Outcome(10.0, SolveStatus.SOLVED, "taut {1,2,3,4}", "OK", {}, {"roll": 0.011}, r, "",
                          "tilt measured; the model agrees", ((0.0,) * 4, (1.0,) * 4))
        encoded = [Encoded([("/platform/pose", "geometry_msgs/msg/PoseStamped", b"\x00\x01")], outcome, None),
                   Encoded([], outcome._replace(stamp=10.1), None)]
        back = _encoded(_plain(encoded))
        assert back == encoded and all(type(e.outcome) is Outcome for e in back)
        assert r is None or all(type(e.outcome.residuals) is Residuals for e in back)
    assert _encoded(_plain([])) == []
