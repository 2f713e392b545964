"""The node's window updates, worked out in a process of its own beside its samples.

At the end of each update window the estimator updates the model's error and the tracked
parameters from the window's samples (`estimator.WindowUpdate`): tens of milliseconds, most
of it the tracked parameters' information, a forward difference of the model per parameter.
Worked out in a thread beside the node's samples it held the interpreter's lock against them,
and the samples estimated meanwhile took twice as long. Here it runs in a process of its own,
on the other core. The update is a function of what it is sent and the plant file's model,
which the process builds once from the plant (a user's effects are loaded there as the plant
file names them; they need not pickle): the same update as worked out at once in replay.
"""
from __future__ import annotations

import multiprocessing
import pickle
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any

from ..effects import PlantModel
from ..model.plantfile.plant import Plant

_base: PlantModel | None = None  # the update process's model of the plant file (`_load`)


class UpdateProcess:
    """Window updates (anything with `run(base_model)`) worked out, one at a time, in a process of its own."""

    def __init__(self, plant: Plant, solver: str = "energy"):
        # forkserver: the process is not forked from the node's, whose DDS threads may hold locks at the fork
        context = multiprocessing.get_context("forkserver")
        self._pool = ProcessPoolExecutor(1, mp_context=context, initializer=_load,
                                         initargs=(plant, solver))

    def submit(self, update: Any) -> Future:
        """Work `update` out there; it is pickled now, so that it carries the state it was made with."""
        return self._pool.submit(_run, pickle.dumps(update))

    def close(self) -> None:
        """Stop the process (an update under way is dropped)."""
        self._pool.shutdown(wait=False, cancel_futures=True)


def _load(plant: Plant, solver: str) -> None:
    global _base
    _base = PlantModel.from_plant(plant, solver)


def _run(update: bytes) -> Any:
    assert _base is not None  # the pool's initializer built it
    return pickle.loads(update).run(_base)
