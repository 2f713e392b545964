"""The node's window updates, worked out in a process of its own beside its samples.

At the end of each update window the estimator updates the model's error and the tracked
parameters from the window's samples (`estimator.WindowUpdate`): tens of milliseconds, most
of it the tracked parameters' information, a forward difference of the model per parameter.
Worked out in a thread beside the node's samples it held the interpreter's lock against them,
and the samples estimated meanwhile took twice as long. Here it runs in a process of its own,
on the other core. The update is a function of what it is sent and the plant file's model,
which the process builds once from the plant (a user's effects are loaded there as the plant
file names them; they need not pickle): the same update as worked out at once in replay.

The process can be lost (killed by the kernel for memory, a user's effect crashing the
interpreter). The node goes on: an update the process did not answer is worked out in the
node's own process from what was sent (the same update), a new process is started for the
next one, and /diagnostics counts the losses and says why the last one happened.

A stop never waits for the process: `close` ends it, and an update it has not answered is
worked out where it was awaited (else the node's exit would wait, at the interpreter's end,
for an update under way, or for ever for a process that hung).
"""
from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
from concurrent.futures import CancelledError, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from ..effects import PlantModel
from ..model.plantfile.plant import Plant

_base: PlantModel | None = None  # the update process's model of the plant file (`_load`)
ANSWER_POLL = 0.2  # [s] between looks, while an update's answer is awaited, at whether the process was closed


class UpdateProcess:
    """Window updates (anything with `run(base_model)`) worked out, one at a time, in a process of its own."""

    def __init__(self, plant: Plant, solver: str = "energy"):
        self._plant, self._solver = plant, solver
        self._context = multiprocessing.get_context("forkserver")
        self._started = self._context.Queue()  # each process puts its id there when it has started
        self._pid: int | None = None
        self._pool = self._start()
        self.losses = 0  # processes lost so far
        self.last_loss = ""  # why the last one was lost
        self._noted: ProcessPoolExecutor | None = None  # the last process whose loss was counted
        self.closed = False

    def _start(self) -> ProcessPoolExecutor:
        # forkserver: the process is not forked from the node's, whose DDS threads may hold locks at the fork
        while not self._started.empty():  # a lost process's id, not read before it was lost
            self._started.get()
        self._pid = None
        return ProcessPoolExecutor(1, mp_context=self._context, initializer=_load,
                                   initargs=(self._plant, self._solver, self._started))

    def submit(self, update: Any) -> PendingUpdate:
        """Work `update` out there; it is pickled now, so that it carries the state it was made with. A process
        lost since the last update is replaced first; after `close`, it is worked out where it is awaited."""
        sent = pickle.dumps(update)
        try:
            return PendingUpdate(self, self._pool, self._pool.submit(_run, sent), sent)
        except BrokenProcessPool as lost:
            if self.closed:
                return self._dropped(sent)
            self.note_lost(self._pool, lost)
            self._pool.shutdown(wait=False)
            self._pool = self._start()
            return PendingUpdate(self, self._pool, self._pool.submit(_run, sent), sent)
        except RuntimeError:  # "cannot schedule new futures after shutdown"
            if not self.closed:
                raise
            return self._dropped(sent)

    def _dropped(self, sent: bytes) -> PendingUpdate:
        """An update sent after `close` (the node is stopping): worked out where it is awaited."""
        dropped: Future = Future()
        dropped.cancel()
        return PendingUpdate(self, self._pool, dropped, sent)

    def note_lost(self, pool: ProcessPoolExecutor, why: BrokenProcessPool) -> None:
        """Count a lost process once, however many of its updates found it gone (one ended by `close` is not lost)."""
        if pool is not self._noted and not self.closed:
            self._noted = pool
            self.losses += 1
            self.last_loss = str(why) or type(why).__name__

    def process_ids(self) -> list[int]:
        """The process's id, once started (for supervision: ps, kill)."""
        while not self._started.empty():
            self._pid = self._started.get()
        return [] if self._pid is None else [self._pid]

    def close(self) -> None:
        """End the process, with any update under way: an update awaited is worked out where it is awaited."""
        self.closed = True
        running = self.process_ids()
        self._pool.shutdown(wait=False, cancel_futures=True)
        for pid in running:
            try:
                os.kill(pid, signal.SIGKILL)  # it holds nothing that must be kept: the node's state is its own
            except ProcessLookupError:
                pass
        self._started.close()


class PendingUpdate:
    """An update sent to the process: its answer, or, where the process was lost before it answered, the same
    update worked out here from what was sent."""

    def __init__(self, process: UpdateProcess, pool: ProcessPoolExecutor, future: Future, sent: bytes):
        self.process, self.pool, self.future, self.sent = process, pool, future, sent

    def result(self, base: PlantModel) -> Any:
        """The update's result (`base`: the plant file's model, for an update worked out here: where the process
        was lost, or closed, before it answered)."""
        while True:
            try:
                return self.future.result(timeout=ANSWER_POLL)
            except TimeoutError:
                if self.process.closed:
                    break
            except BrokenProcessPool as lost:
                self.process.note_lost(self.pool, lost)
                break
            except CancelledError:
                break
        return pickle.loads(self.sent).run(base)


def _load(plant: Plant, solver: str, started: Any) -> None:
    global _base
    _base = PlantModel.from_plant(plant, solver)
    started.put(os.getpid())


def _run(update: bytes) -> Any:
    assert _base is not None  # the pool's initializer built it
    return pickle.loads(update).run(_base)
