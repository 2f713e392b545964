"""How far a recording's log times run from its header stamps, where they differ by a constant.

A recorder whose clock is not the winches' (no time server in the shaft, a bag recorded
again later) logs every message a constant time after or before its stamp. Against the
log time as the clock, the stamp window (monitor.inputs.StampWindow) would then refuse
every winch message of the bag, and a replay would end with nothing solved. Where the
first winch messages all lie the same distance from their log times, outside the window
but within it of each other, that distance is the recording's clock offset: the replay
judges the stamps against the log time less it, and says so.
"""
from __future__ import annotations

from pathlib import Path

from ..bagio.reader import BagReader
from ..channels import JOINT_STATE, WINCH_TOPICS
from ..monitor.inputs import StampWindow
from . import fields

SAMPLE = 100  # winch messages the offset is taken from


def _median(values: list[float]) -> float:
    """np.median's value, without the import of numpy.ma (13 ms of every replay's start) its first call makes."""
    ordered, middle = sorted(values), len(values) // 2
    return ordered[middle] if len(values) % 2 else (ordered[middle - 1] + ordered[middle]) / 2


def clock_offset(bag: str | Path, window: StampWindow) -> tuple[StampWindow, str]:
    """`window` with the recording's clock offset, and a note saying it ('' and `window` itself where the
    stamps lie within the window of their log times, or do not agree on one offset)."""
    lags = []
    for item in BagReader(bag, dict.fromkeys(WINCH_TOPICS, JOINT_STATE)):
        lags.append(item.log_time * 1e-9 - fields.message_seconds(item.message, item.log_time))
        if len(lags) == SAMPLE:
            break
    if not lags:
        return window, ""
    offset = _median(lags)
    shifted = StampWindow(window.ahead, window.behind, window.skew, offset)
    if window.holds(offset) or not all(shifted.holds(lag) for lag in lags):
        return window, ""
    side = "behind" if offset > 0 else "ahead of"
    return shifted, (f"the winches' header stamps lie {abs(offset):.3f} s {side} the log times throughout the first "
                     f"{len(lags)} winch messages (the recorder kept another clock): their stamps are judged against "
                     f"the log time {'less' if offset > 0 else 'plus'} {abs(offset):.3f} s")
