"""The live node under `use_sim_time`, with a real /clock publisher over loopback DDS: a clock that jumps back
(a bag played with --loop) resets the stamp history and says so; readings stamped far ahead of the clock are
an error; the alarm turns to no data once its sample is stale; messages before the first /clock are used; a
SIGINT stops the node with no /clock coming even where the signal's own wake-up of the executor is lost.

Before, every message after a jump back was refused as "stamp not increasing" for the whole loop while
/diagnostics showed the alarm frozen at its last level, and messages before the first /clock were refused as
stamped 1000 s ahead of a clock reading 0."""
from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from builtin_interfaces.msg import Time
from ros_harness import INPUTS_STATUS, PARAMS_FILE, LiveNode, input_value, rejected_count, ros_env, stamp_from_ns
from rosgraph_msgs.msg import Clock

pytestmark = pytest.mark.timeout(90)

ALARM_STATUS = "winch_monitor: collision alarm"
GOOD = (20.0, 20.0, 20.0, 20.0)
ERROR_LEVEL, STALE_LEVEL = 2, 3
START = 1000.0  # [s] the simulated time a recording starts at


class SimClock:
    """/clock from this process at 50 Hz, running at the wall clock's rate from START; `jump` sets it."""

    def __init__(self, live: LiveNode):
        self.publisher = live.client.node.create_publisher(Clock, "/clock", 10)
        deadline = time.monotonic() + 10.0
        while self.publisher.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "the node does not subscribe to /clock"
            time.sleep(0.05)
        self.lock = threading.Lock()
        self.base, self.started = START, time.monotonic()
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def now(self) -> float:
        with self.lock:
            return self.base + time.monotonic() - self.started

    def stamp(self) -> Time:
        return stamp_from_ns(int(round(self.now() * 1e9)))

    def start(self) -> SimClock:
        self.thread.start()
        return self

    def jump(self, to: float) -> None:
        with self.lock:
            self.base, self.started = to, time.monotonic()

    def _run(self) -> None:
        while not self.stopped.is_set():
            self.publisher.publish(Clock(clock=self.stamp()))
            time.sleep(0.02)

    def stop(self) -> None:
        self.stopped.set()
        if self.thread.is_alive():
            self.thread.join(timeout=2.0)


@pytest.fixture
def sim():
    live = LiveNode({"use_sim_time": True, "diagnostics_period": 0.2}, warm_up=False)
    clock = None
    try:
        clock = SimClock(live)
        yield live, clock
    finally:
        if clock is not None:
            clock.stop()
        code = live.close()  # whatever failed: no node is left running in a domain another test will lease
    assert code == 0


def lowering(live: LiveNode, clock: SimClock, seconds: float) -> list[Time]:
    """Samples stamped with the simulated clock every 50 ms for `seconds`, paying out 0.1 m/s."""
    stamps = []
    for _ in range(int(seconds / 0.05)):
        stamp = clock.stamp()
        payout = 20.0 + 0.1 * (stamp.sec + stamp.nanosec * 1e-9 - START)
        stamps.append(live.client.publish((payout,) * 4, stamp=stamp))
        time.sleep(0.05)
    return stamps


def test_messages_before_the_first_clock_are_used(sim):
    live, clock = sim
    stamp = stamp_from_ns(int(START * 1e9))
    assert live.client.outputs(live.client.publish(GOOD, stamp=stamp), pose=True).pose is not None
    clock.jump(START + 0.1)
    clock.start()
    statuses = live.client.diagnostics(lambda s: True, "any status after the first /clock")
    assert rejected_count(statuses, "stamp ahead of the clock") == 0
    assert int(input_value(statuses, "/winch/joint_states used")) == 1


def test_a_clock_jump_back_resets_the_stamps_and_is_said(sim):
    live, clock = sim
    clock.start()
    first = lowering(live, clock, 1.5)
    live.client.outputs(first[-1], pose=True)
    clock.jump(START)  # the bag plays again from its start
    statuses = live.client.diagnostics(lambda s: input_value(s, "clock jumps back") == "1", "the jump back")
    level, message, values = statuses[INPUTS_STATUS]
    assert "clock went back 1." in values["last clock jump"] and "stamp history reset" in message, message
    assert level >= 1
    again = lowering(live, clock, 1.0)
    assert live.client.outputs(again[-1], pose=True).pose is not None
    statuses = live.client.diagnostics(lambda s: True, "any status after the loop")
    assert rejected_count(statuses, "stamp not increasing") == 0


def test_readings_stamped_ahead_of_the_clock_are_an_error_and_their_alarm_no_data(sim):
    """A winch on the wall clock while /clock replays a recording: its stamps lie far ahead of the clock."""
    live, clock = sim
    ahead = stamp_from_ns(int((START + 4000.0) * 1e9))
    live.client.outputs(live.client.publish(GOOD, stamp=ahead), pose=True)  # before /clock: used
    clock.start()
    statuses = live.client.diagnostics(lambda s: s[INPUTS_STATUS][0] == ERROR_LEVEL, "inputs in ERROR")
    assert "stamped ahead of the clock (> 2 s): cable_1 (3999." in statuses[INPUTS_STATUS][1]
    level, message, _ = statuses[ALARM_STATUS]
    assert level == STALE_LEVEL and message.startswith("no data: the last sample is stamped 3999."), message


def test_the_alarm_is_no_data_once_its_sample_is_stale(sim):
    live, clock = sim
    clock.start()
    stamps = lowering(live, clock, 0.5)
    live.client.outputs(stamps[-1], pose=True)
    statuses = live.client.diagnostics(lambda s: s[ALARM_STATUS][0] != STALE_LEVEL, "the alarm of a fresh sample",
                                       timeout=2.0)
    assert statuses[ALARM_STATUS][1].startswith("OK"), statuses[ALARM_STATUS]
    statuses = live.client.diagnostics(lambda s: s[ALARM_STATUS][0] == STALE_LEVEL, "the alarm with no data")
    message = statuses[ALARM_STATUS][1]
    assert message.startswith("no data: the last sample is ") and " s old (it was OK" in message, message


WITHOUT_SIGINT_WAKE = Path(__file__).resolve().parents[1] / "helpers" / "node_without_sigint_wake.py"


def test_a_sigint_stops_the_node_with_no_clock_even_where_its_wake_up_is_lost(domain_id, tmp_path):
    """A node under use_sim_time whose executor no SIGINT wakes (rclpy's signal guard condition taken away,
    as a node was once seen waiting for ever after one) and that no /clock wakes either: its steady wake-up
    lets Python raise the pending KeyboardInterrupt, and it ends cleanly within two seconds."""
    log = tmp_path / "node.log"
    with open(log, "w") as out:
        node = subprocess.Popen([sys.executable, str(WITHOUT_SIGINT_WAKE), "--ros-args", "--params-file",
                                 str(PARAMS_FILE), "-p", "use_sim_time:=true"], env=ros_env(domain_id), stdout=out,
                                stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + 30.0
            while "monitoring plant" not in log.read_text():
                assert node.poll() is None and time.monotonic() < deadline, log.read_text()[-2000:]
                time.sleep(0.05)
            time.sleep(0.5)  # spinning: the executor waits with nothing to wake it but the signal
            node.send_signal(signal.SIGINT)
            started = time.monotonic()
            code = node.wait(timeout=10.0)
        finally:
            if node.poll() is None:
                node.kill()
                node.wait()
    assert code == 0 and time.monotonic() - started < 2.0, log.read_text()[-2000:]
    assert "Traceback" not in log.read_text()
