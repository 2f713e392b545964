"""SIGINT, SIGTERM and SIGHUP as a clean stop of a long job that writes a file.

By default SIGTERM and SIGHUP end Python at once (no `finally`, no file closed) and SIGINT
raises KeyboardInterrupt wherever the program is, in the middle of a record if it is
writing one. Inside `stop_signals()` each of them is taken as a request to stop: raised as
`Stopped` at once where the job is in an `interruptible()` stretch (waiting, computing),
else held until it enters the next one, so that what is written stays whole. Once a stop
is under way, further signals are ignored: stopping is short and must not be broken off;
a program that only reports and exits after it ignores them too (`ignore_stop_signals`).
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Stopped(KeyboardInterrupt):
    """The job was asked to stop by a signal (its name in `signal`)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signal = signal.Signals(signum).name


class _State:
    armed = False              # in an interruptible stretch
    signum: int | None = None  # the stop asked for


_state = _State()


def _handle(signum: int, _frame: Any) -> None:
    if _state.signum is not None:
        return  # already stopping
    _state.signum = signum
    if _state.armed:
        raise Stopped(signum)


@contextmanager
def stop_signals() -> Iterator[None]:
    """Stop signals taken as Stopped inside (in the main thread, the only one a signal reaches; elsewhere
    nothing changes); the handlers before are put back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.signal(signum, _handle) for signum in SIGNALS}
    _state.signum = None
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        _state.signum, _state.armed = None, False


@contextmanager
def interruptible() -> Iterator[None]:
    """A stretch a stop may break off at once; a stop asked for before it is raised on entry."""
    if _state.signum is not None:
        raise Stopped(_state.signum)
    armed, _state.armed = _state.armed, True
    try:
        yield
    finally:
        _state.armed = armed


def ignore_stop_signals() -> None:
    """Further stop signals ignored, in a program that was stopped and only reports and exits: a second
    Ctrl-C must break off neither (Python's exit would take it as the default's: killed, no status)."""
    if threading.current_thread() is threading.main_thread():
        for signum in SIGNALS:
            signal.signal(signum, signal.SIG_IGN)
