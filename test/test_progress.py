"""Progress estimates: within a factor of 2 of the real time left after the first tenth, start-up excluded."""
from __future__ import annotations

import io

import pytest

from cable_winch_monitor.progress import Progress


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("startup, costs", [
    (1.0, [0.004] * 1000),                      # replay of a 4 s job after a second of start-up
    (5.0, [0.002] * 500 + [0.003] * 500),       # the second half half as slow again
    (0.0, [0.05 if k % 10 == 0 else 0.001 for k in range(2000)]),  # windows: one slow item in ten
])
def test_time_left_within_a_factor_of_two_after_the_first_tenth(startup, costs):
    clock, stream = Clock(), Terminal()
    bar = Progress("replay", len(costs), stream=stream, clock=clock)
    clock.now += startup
    remaining = sum(costs)
    for done, cost in enumerate(costs, 1):
        clock.now += cost
        remaining -= cost
        bar.update(done)
        left = bar.left(done, clock.now)
        if done >= len(costs) / 10 and remaining > 0.05 * sum(costs):
            assert left is not None and remaining / 2 <= left <= 2 * remaining, (done, left, remaining)
    bar.finish()
    assert "s left" in stream.getvalue() and stream.getvalue().endswith("\n")


def test_only_on_a_terminal_when_asked():
    clock, piped = Clock(), io.StringIO()
    bar = Progress("diagnose", 10, stream=piped, clock=clock, only_tty=True)
    for done in range(1, 11):
        clock.now += 1.0
        bar.update(done)
    assert piped.getvalue() == ""
