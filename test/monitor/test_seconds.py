"""The first sample of each second of stamps, where the tracked parameters are published."""
from __future__ import annotations

from cable_winch_monitor.monitor.seconds import FirstOfEachSecond


def test_one_first_sample_a_second_whatever_the_winches_order_and_again_after_a_restart():
    """A sample made at another winch's message, stamped a little before the one before it and so across the
    start of a second, is not a second's first; stamps back by more than a second (a simulation restarted)
    start over."""
    first = FirstOfEachSecond()
    stamps = [4.2, 4.9, 5.001, 4.999, 5.003, 5.5, 5.999, 6.0, 7.4, 2.0, 2.1, 3.05]
    assert [first(stamp) for stamp in stamps] == [True, False, True, False, False, False, False, True, True, True,
                                                  False, True]
