"""`replay` stopped by a signal, or its second process stopped: real processes, real signals, real MCAP files.

A replay forks a worker and spools windows through /dev/shm (replay/second_process.py, replay/worker.py). Whatever stops
either process, nothing may be left: no worker, no spool folder, and (SIGINT, SIGTERM, SIGHUP) an output
bag with its footer and metadata that mcap and rosbags read, holding exactly what the summary counts.
A worker that stops answering is given up after a bounded wait and the replay finishes by itself; a slow
user hook does not keep a Ctrl-C waiting; the spool follows TMPDIR where /dev/shm cannot be written.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import suppress
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from simbags import CLI, simulated

from cable_winch_monitor.paths import default_plant_file
from cable_winch_monitor.replay import replay
from cable_winch_monitor.replay import worker as forked

SPOOL_PREFIX = "cable-winch-monitor-"
STOPPED_WITHIN = 5.0  # [s] from the signal to the replay's exit

SPINNING_HOOK = '''
import time
from cable_winch_monitor.effects import Effect, Parameter


class SlowLoad(Effect):
    """A user's hook that takes its time on every call (busy: the worker uses CPU throughout)."""

    name, acts = "slow_load", "load"
    parameters = (Parameter("k", "-", 0.0, (-1.0, 1.0), 0.1, "unused"),)

    def load(self, wrench, plant, conditions):
        end = time.perf_counter() + 0.05
        while time.perf_counter() < end:
            pass
        return wrench
'''


@pytest.fixture(scope="module")
def long_bag(tmp_path_factory) -> Path:
    """A bag long enough (200 s of all channels, ~10,000 messages, ~8,000 samples) for a signal to land
    mid-replay."""
    return simulated(tmp_path_factory.mktemp("signals"), "all_channels", "duration=200")


@pytest.fixture(scope="module")
def slow_plant(tmp_path_factory) -> Path:
    """The bundled plant with a user effect whose hook takes 50 ms a call."""
    folder = tmp_path_factory.mktemp("slow")
    (folder / "slow.py").write_text(SPINNING_HOOK)
    config = yaml.safe_load(default_plant_file().read_text())
    config["plant"]["effect_modules"] = ["slow.py"]
    config["plant"]["effects"] = {"slow_load": {"k": 0.1}}
    path = folder / "slow.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


class Replay:
    """`cable-winch-monitor replay BAG --out OUT --quiet ARGS` in a process group of its own, TMPDIR in `tmp`."""

    def __init__(self, bag: Path, out: Path, tmp: Path, *args: str | Path, prefix: tuple[str, ...] = ()):
        tmp.mkdir(exist_ok=True)
        self.out, self.tmp = out, tmp
        env = dict(os.environ, TMPDIR=str(tmp))
        self.process = subprocess.Popen([*prefix, *CLI, "replay", str(bag), "--out", str(out), "--quiet",
                                         *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, env=env, start_new_session=True)
        self.pid = self.process.pid

    def worker(self, timeout: float = 60.0) -> int:
        """The forked worker's pid, once there is one."""
        wait_for(lambda: children(self.pid), timeout, "the replay forked no worker")
        (pid,) = children(self.pid)
        return pid

    def spools(self) -> list[Path]:
        """The replay's spool folders in /dev/shm and in TMPDIR."""
        return [*Path(forked.SPOOL).glob(f"{SPOOL_PREFIX}{self.pid}-*"), *self.tmp.glob(f"{SPOOL_PREFIX}{self.pid}-*")]

    def under_way(self, timeout: float = 60.0) -> None:
        """Wait until the output bag holds a first chunk of records (some were written)."""
        def written() -> bool:
            return any(f.stat().st_size > 1_000_000 for f in self.out.glob("*.mcap"))
        wait_for(written, timeout, "the replay wrote nothing")

    def finish(self, timeout: float) -> tuple[int, str, str]:
        stdout, stderr = self.process.communicate(timeout=timeout)
        return self.process.returncode, stdout, stderr

    def kill(self) -> None:
        """Whatever of it a failed test left running (its worker may have a session of its own: pid by pid)."""
        for pid in [*children(self.pid), self.pid]:
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        self.process.communicate()


@pytest.fixture
def start(tmp_path) -> Iterator[Callable[..., Replay]]:
    """Start replays (TMPDIR in the test's folder); those a failed test left running are killed."""
    runs: list[Replay] = []

    def started(bag: Path, out: Path, *args: str | Path, prefix: tuple[str, ...] = ()) -> Replay:
        runs.append(Replay(bag, out, tmp_path / "tmp", *args, prefix=prefix))
        return runs[-1]
    yield started
    for run in runs:
        if run.process.poll() is None:
            run.kill()


def wait_for(condition: Callable[[], object], timeout: float, failure: str) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, failure
        time.sleep(0.05)


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def running(pid: int) -> bool:
    """The process exists and is not a zombie (a zombie has ended: it holds no memory, only its exit status)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def bag_counts(out: Path) -> Counter[str]:
    """Messages per topic of a finished bag, by rosbags (metadata.yaml) and by mcap (footer, summary,
    every message), which must agree."""
    with Reader(out) as reader:
        by_rosbags = Counter(c.topic for c, _, _ in reader.messages())
        assert reader.message_count == sum(by_rosbags.values())
    (file,) = out.glob("*.mcap")
    with file.open("rb") as stream:
        mcap = make_reader(stream)
        summary = mcap.get_summary()
        assert summary is not None and summary.statistics is not None, "no summary: the bag was not finished"
        by_mcap = Counter(channel.topic for _, channel, _ in mcap.iter_messages())
        assert summary.statistics.message_count == sum(by_mcap.values())
    assert by_rosbags == by_mcap
    return by_mcap


def input_messages(bag: Path) -> int:
    with Reader(bag) as reader:
        return reader.message_count


def summary_counts(stdout: str) -> tuple[Counter[str], int, int]:
    """From replay's summary: messages read per input topic, outputs written, samples."""
    read = Counter({m[1]: int(m[2]) for m in re.finditer(r"^(/\S+)\s+\S+/msg/\S+\s+(\d+)", stdout, re.M)})
    written = int(re.search(r"^written: (\d+) messages", stdout, re.M)[1])
    samples = int(re.search(r"^samples: (\d+)", stdout, re.M)[1])
    return read, written, samples


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_stop_signal_leaves_no_process_nor_spool_and_a_finished_bag_of_what_was_counted(long_bag, start, tmp_path,
                                                                                          signum):
    run = start(long_bag, tmp_path / "out")
    worker = run.worker()
    run.under_way()
    assert run.spools() and running(worker)
    sent = time.monotonic()
    os.kill(run.pid, signum)
    code, stdout, stderr = run.finish(timeout=60)
    took = time.monotonic() - sent
    assert code == 1 and "Traceback" not in stdout + stderr, stdout + stderr
    assert f"INTERRUPTED by {signum.name}: replay stopped after" in stdout
    assert took < STOPPED_WITHIN, f"{took:.1f} s to stop"
    assert not running(worker) and not run.spools()
    read, written, samples = summary_counts(stdout)
    in_bag = bag_counts(tmp_path / "out")
    assert 0 < sum(read.values()) < input_messages(long_bag), "stopped mid-replay"
    assert f"replay stopped after {sum(read.values())} messages" in stdout
    assert {t: n for t, n in in_bag.items() if t in read} == read, "the summary counts messages read ahead"
    assert sum(n for t, n in in_bag.items() if t not in read) == written
    assert in_bag["/cables/tension"] == samples


def test_sigkill_leaves_no_worker_nor_spool(long_bag, start, tmp_path):
    run = start(long_bag, tmp_path / "out")
    worker = run.worker()
    run.under_way()
    spools = run.spools()
    assert spools
    os.kill(run.pid, signal.SIGKILL)
    assert run.finish(timeout=10)[0] == -signal.SIGKILL
    wait_for(lambda: not running(worker), 5.0, "the worker outlived its replay")
    wait_for(lambda: not any(s.exists() for s in spools), 5.0, "the spool outlived the replay")


def test_a_stopped_worker_is_given_up_and_the_replay_finishes_the_same_bag_itself(long_bag, start, tmp_path):
    (tmp_path / "two").mkdir()
    run = start(long_bag, tmp_path / "two" / "out")
    worker = run.worker()
    run.under_way()
    os.kill(worker, signal.SIGSTOP)
    stopped = time.monotonic()
    try:
        code, stdout, stderr = run.finish(timeout=300)
    finally:
        if running(worker):
            os.kill(worker, signal.SIGKILL)
    assert code == 0 and "Traceback" not in stdout + stderr, stdout + stderr
    assert f"note: second process given up (the worker has not answered for {forked.STALL:g} s): the rest was " \
        "replayed in this process" in stdout
    assert time.monotonic() - stopped > forked.STALL
    assert not running(worker) and not run.spools()
    one = replay(long_bag, tmp_path / "one" / "out", progress=False, second_process=False)
    assert one.complete
    files = [sorted((tmp_path / name / "out").glob("*.mcap")) for name in ("one", "two")]
    assert [f.read_bytes() for f in files[0]] == [f.read_bytes() for f in files[1]]


@pytest.mark.parametrize("hook_in", ["worker", "replay"])
def test_one_ctrl_c_stops_a_slow_hook_at_once_and_a_second_does_not_hang(slow_plant, start, tmp_path, hook_in):
    """Ctrl-C at a terminal: SIGINT to the whole process group, while the hook runs in the worker, or in the
    replay's own process once the worker is given up (stopped). A second Ctrl-C, 0.1 s after the first while
    it stops or exits, is ignored: the summary and the exit status are given all the same."""
    bag = simulated(tmp_path, "all_channels", "duration=12")
    run = start(bag, tmp_path / "out", "--config", slow_plant)
    worker = run.worker()
    if hook_in == "replay":
        os.kill(worker, signal.SIGSTOP)
        wait_for(lambda: not running(worker), forked.STALL + 30.0, "the stopped worker was not given up")
    time.sleep(2.0)  # in the hook, a window's worth of it ahead
    assert run.process.poll() is None
    sent = time.monotonic()
    os.killpg(run.pid, signal.SIGINT)
    time.sleep(0.1)
    if run.process.poll() is None:
        os.killpg(run.pid, signal.SIGINT)
    code, stdout, stderr = run.finish(timeout=60)
    took = time.monotonic() - sent
    assert code == 1 and "Traceback" not in stdout + stderr, stdout + stderr
    assert "INTERRUPTED by SIGINT" in stdout and took < STOPPED_WITHIN, f"{took:.1f} s to stop"
    assert not running(worker) and not run.spools()
    read, written, samples = summary_counts(stdout)
    assert bag_counts(tmp_path / "out")["/cables/tension"] == samples


def unshare_works() -> bool:
    try:
        return subprocess.run(["unshare", "--mount", "true"], capture_output=True).returncode == 0
    except OSError:
        return False


@pytest.mark.skipif(not unshare_works(), reason="needs a mount namespace of its own (unshare --mount)")
def test_a_read_only_dev_shm_sends_the_spool_to_tmpdir(long_bag, start, tmp_path):
    """/dev/shm mounted read-only in the replay's own mount namespace: the worker spools in TMPDIR."""
    read_only = ["unshare", "--mount", "sh", "-c",
                 "mount -t tmpfs -o ro tmpfs /dev/shm && exec \"$@\"", "sh"]
    run = start(long_bag, tmp_path / "out", prefix=tuple(read_only))
    wait_for(lambda: list(run.tmp.glob(f"{SPOOL_PREFIX}{run.pid}-*")), 60.0, "no spool in TMPDIR")
    code, stdout, stderr = run.finish(timeout=300)
    assert code == 0 and "Traceback" not in stdout + stderr, stdout + stderr
    assert "given up" not in stdout and not run.spools()
    read, written, samples = summary_counts(stdout)
    assert sum(read.values()) == input_messages(long_bag)
    assert bag_counts(tmp_path / "out")["/cables/tension"] == samples > 0
