"""Replay's second process: it runs the window stages while the replay reads, merges and writes.

Replay merges each window of messages (cheap, in log order) and hands its complete samples
to a forked process that runs the stages on them (stages.py), window after window, while
it reads and merges the next ones; it then writes the records the worker encoded, in log
order, with the sensor messages' residuals between them. What comes back is bytes and small
outcomes, not objects per sample, whose pickling would cost as much as the work.

A window's job and its results (about 1 kB a sample) go through files in the worker's spool
(worker.py: /dev/shm, or TMPDIR where that cannot be written), not a pipe, which would make
either process wait for the other to read. With each window comes the stages' state after
it, so that where the worker is lost -- it died, failed on a window, or stopped answering --
the replay runs the rest itself from there. Samples cross as plain tuples, a window's lengths as one
array (`_packed`), and the outcomes come back as columns, their residuals plain tuples (`_plain`):
pickling a named tuple or a small array per sample cost more than the rest of the crossing. The
samples' conditions are the worker's to work out (the stages). Only a fork can start it (the process
inherits the plant model as it is, a user's effects included); where there is none, or no spool or
process can be had, the replay runs the stages itself.
"""
from __future__ import annotations

import functools
import os
import pickle
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..messages.fields import Stamp
from ..monitor.pipeline import CompleteSample
from ..monitor.residuals import Residuals
from .stages import Encoded, Staged, WindowStages
from .worker import ForkedWorker, WorkerLost

Packed = tuple[np.ndarray, list[tuple[Any, ...]]]  # a window's lengths (n, 4), each sample's other fields
LENGTHS = CompleteSample._fields.index("lengths")


def _packed(samples: Sequence[CompleteSample]) -> Packed:
    """A window's samples as they cross to the worker: their lengths as one array, the rest plain tuples."""
    return np.array([s.lengths for s in samples]), [(*s[:LENGTHS], *s[LENGTHS + 1:]) for s in samples]


def _unpacked(packed: Packed) -> list[CompleteSample]:
    lengths, rows = packed
    return [CompleteSample._make((*row[:LENGTHS], row_lengths, *row[LENGTHS:])) for row_lengths, row in zip(lengths, rows)]


def _plain(staged: Staged) -> tuple[bytes, ...]:
    """A window's `Staged` from the worker (never with their outputs) as it crosses: its records, outcomes (columns;
    their residuals apart, as plain tuples), /diagnostics views and scenes, each pickled apart (pickled together,
    every object of the window shares one memo: 46 against 31 ms for (a)'s windows, 69 against 54 ms to read them
    back)."""
    outcomes = staged.outcomes
    residuals = [None if r is None else tuple(r) for r in outcomes.residuals]
    return tuple(pickle.dumps(part, protocol=pickle.HIGHEST_PROTOCOL) for part in
                 (staged.records, replace(outcomes, residuals=[]), residuals, staged.views, staged.scenes))


def _encoded(plain: tuple[bytes, ...]) -> list[Encoded]:
    records, outcomes, residuals, views, scenes = (pickle.loads(part) for part in plain)
    outcomes = replace(outcomes, residuals=[None if r is None else Residuals._make(r) for r in residuals])
    return Staged(records, outcomes, views, scenes).encoded()


def _job(stages: WindowStages, job: tuple[Any, ...]) -> tuple[tuple[bytes, ...], bytes]:
    """The worker's job: a window's samples through the stages (without the outputs themselves) and the stages'
    state after them."""
    samples, inputs, headers, batched = job
    return _plain(stages.run(_unpacked(samples), inputs, headers, batched, outputs=False)), stages.state()


class SecondProcess:
    """A worker process running the window stages in order for a replay (forked before it merges); where it
    cannot be started, or is lost, the windows are run here."""

    def __init__(self, stages: WindowStages):
        self.local = stages
        try:
            self.worker: ForkedWorker | None = ForkedWorker(functools.partial(_job, stages),
                                                            f"cable-winch-monitor-{os.getpid()}-")
        except OSError:
            self.worker = None  # no spool folder or no process to be had: run here
        self.pending: list[tuple[bool, tuple[Any, ...]]] = []  # (handed to the worker, job) in order
        self.state: bytes | None = None  # the worker's state after the last window taken from it
        self.lost = ""  # why the worker was given up, where it was

    @staticmethod
    def available() -> bool:
        return ForkedWorker.available()

    def submit(self, samples: list[CompleteSample], inputs: list[dict[str, float]] | None, headers: list[Stamp],
               batched: bool) -> None:
        """Start a window's samples (with the extra inputs' values at their stamps, None where the plant reads
        none) through the stages in the worker (in order after the windows before it)."""
        job = (samples, inputs, headers, batched)
        if self.worker is not None:
            try:
                self.worker.submit((_packed(samples), inputs, headers, batched))
            except WorkerLost as lost:
                self._lost(str(lost))
        self.pending.append((self.worker is not None, job))

    def take(self) -> list[Encoded]:
        """The oldest submitted window's samples encoded: the worker's, or run here from the worker's last
        state where it was lost, failed on the window, or stopped answering."""
        handed, job = self.pending.pop(0)
        if handed and self.worker is not None:
            try:
                result, self.state = self.worker.result()
                return _encoded(result)
            except WorkerLost as lost:
                self._lost(str(lost))
        if self.state is not None:
            self.local.restore(self.state)
            self.state = None
        return self.local.run(*job).encoded()

    def _lost(self, why: str) -> None:
        """The worker is gone (or could not hand a window over): it is ended, the rest run here."""
        self.lost = why
        self.close()
        self.pending = [(False, job) for _, job in self.pending]

    def close(self) -> None:
        """End the worker, if there is one (killed where it still has work)."""
        if self.worker is not None:
            self.worker.close()
            self.worker = None
