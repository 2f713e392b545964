"""A forked worker process: jobs run in order, each handed over and back as a file in a spool folder.

Replay's second process (second_process.py) is one. A worker must never keep its parent waiting on it,
outlive it, or leave files behind, whatever stops either of them:

- the spool is a new folder in SPOOL (/dev/shm: memory, not a disk), or in tempfile's folder
  (TMPDIR) where SPOOL is missing or cannot be written; the pipes carry only the files'
  names (a window's job through a pipe would make the parent wait until the worker reads it);
- the worker ends with its parent: on Linux the kernel sends it SIGTERM when the parent dies
  (PR_SET_PDEATHSIG, so also after a SIGKILL), elsewhere it ends when the job pipe closes; a
  worker whose parent is gone removes the spool;
- it ignores SIGINT and SIGHUP, which a terminal sends to the whole process group: the parent
  decides what a stop means;
- the parent gives it up (WorkerLost) where it died, failed on a job, or used no CPU time for
  STALL seconds while a result was awaited (stopped by SIGSTOP, or hung); `close` kills a
  worker that still has work, so that a stop never waits for its job.
"""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import pickle
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, NoReturn

SPOOL = "/dev/shm"  # where the files go, where it can be written
STALL = 5.0         # [s] without CPU time used while a result is awaited: the worker is given up
POLL = 0.2          # [s] between looks at a worker that has not answered yet
QUIT = 1.0          # [s] a worker without work is given to end by itself at close
PR_SET_PDEATHSIG = 1


class WorkerLost(Exception):
    """The worker is gone, stopped answering, or could not run a job or hand its result over."""


def spool_folder(prefix: str) -> str:
    """A new folder for the files between the processes: in SPOOL where it can be made, else in tempfile's
    (TMPDIR's) folder; OSError where neither can."""
    if os.path.isdir(SPOOL):
        try:
            return tempfile.mkdtemp(prefix=prefix, dir=SPOOL)
        except OSError:
            pass  # read-only or full: the next place
    return tempfile.mkdtemp(prefix=prefix)


def cpu_time(pid: int) -> int | None:
    """The CPU time process `pid` has used [clock ticks]; None where /proc does not tell."""
    try:
        with open(f"/proc/{pid}/stat") as file:
            fields = file.read().rsplit(")", 1)[1].split()
        return int(fields[11]) + int(fields[12])  # utime, stime
    except (OSError, IndexError, ValueError):
        return None


def _put(folder: str, content: Any) -> str:
    """`content` pickled into a new file in `folder`; its path (nothing is left where it fails)."""
    file = tempfile.NamedTemporaryFile(dir=folder, delete=False)
    try:
        with file:
            pickle.dump(content, file, protocol=pickle.HIGHEST_PROTOCOL)
    except BaseException:
        os.unlink(file.name)
        raise
    return file.name


def _get(path: str) -> Any:
    """What `_put` wrote into `path`; the file is removed."""
    try:
        with open(path, "rb") as file:
            return pickle.load(file)
    finally:
        os.unlink(path)


def _leave(spool: str, parent: int) -> NoReturn:
    """End the worker now; its spool goes with it where the parent is gone (else the parent removes it)."""
    if os.getppid() != parent:
        shutil.rmtree(spool, ignore_errors=True)
    os._exit(0)


def _end_with_parent() -> None:
    """Have the kernel send SIGTERM to this process when its parent dies (Linux)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        except (OSError, AttributeError):
            pass  # then the job pipe's end tells


def _serve(run: Callable[[Any], Any], spool: str, jobs: Connection, results: Connection, parent: int,
           parents_ends: tuple[Connection, Connection]) -> None:
    """The worker: each job named on `jobs` run, its result's file named on `results` (None where it failed:
    the parent runs the job itself, where an error is raised as itself)."""
    for end in parents_ends:
        end.close()  # else the job pipe never ends while this process lives
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: _leave(spool, parent))
    _end_with_parent()
    if os.getppid() != parent:
        _leave(spool, parent)  # died before the kernel was asked
    while True:
        try:
            path = jobs.recv()
        except (EOFError, OSError):
            _leave(spool, parent)  # closed by the parent, or the parent is gone
        try:
            answer = _put(spool, run(_get(path)))
        except Exception:  # any failure: the parent runs the job itself, where an error is raised as itself
            answer = None
        try:
            results.send(answer)
        except OSError:
            _leave(spool, parent)


class ForkedWorker:
    """A forked process running `run(job)` for each job submitted, in order (it inherits everything `run`
    needs as it is at the fork, nothing pickled). OSError where no spool or process can be made."""

    def __init__(self, run: Callable[[Any], Any], prefix: str):
        self.spool = spool_folder(prefix)
        context = multiprocessing.get_context("fork")
        jobs, self._jobs = context.Pipe(duplex=False)
        self._results, results = context.Pipe(duplex=False)
        self.process = context.Process(target=_serve, daemon=True, args=(
            run, self.spool, jobs, results, os.getpid(), (self._jobs, self._results)))
        try:
            self.process.start()
        except OSError:
            shutil.rmtree(self.spool, ignore_errors=True)
            raise
        finally:
            jobs.close()
            results.close()
        self.waiting = 0  # jobs submitted whose results are not taken

    @staticmethod
    def available() -> bool:
        return "fork" in multiprocessing.get_all_start_methods()

    def submit(self, job: Any) -> None:
        """Hand a job over (WorkerLost where it cannot be)."""
        try:
            self._jobs.send(_put(self.spool, job))
        except OSError as error:
            raise WorkerLost(f"cannot hand a job over: {error}") from None
        self.waiting += 1

    def result(self) -> Any:
        """The oldest job's result, waited for while the worker uses CPU time; WorkerLost where it died,
        failed on the job, or used none for STALL seconds."""
        pid = self.process.pid
        assert pid is not None, "the worker is started with the ForkedWorker"
        used, since = cpu_time(pid), time.monotonic()
        while not self._results.poll(POLL):
            if not self.process.is_alive():
                raise WorkerLost("the worker died")
            now, cpu = time.monotonic(), cpu_time(pid)
            if cpu is not None and cpu != used:
                used, since = cpu, now
            elif now - since > STALL:
                raise WorkerLost(f"the worker has not answered for {STALL:g} s")
        try:
            path = self._results.recv()
        except (EOFError, OSError):
            raise WorkerLost("the worker died") from None
        self.waiting -= 1
        if path is None:
            raise WorkerLost("the worker could not run a job or hand its result over")
        try:
            return _get(path)
        except (OSError, EOFError, pickle.UnpicklingError) as error:
            raise WorkerLost(f"cannot read the worker's result: {error}") from None

    def close(self) -> None:
        """End the worker (killed where it still has work: nothing waits for it) and remove the spool."""
        self._jobs.close()
        if self.waiting:
            self.process.kill()
        self.process.join(QUIT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self._results.close()
        shutil.rmtree(self.spool, ignore_errors=True)
