"""Bad input never stops the winch_monitor node and never yields a pose, and each case shows in /diagnostics.

Each case sends the bad input right after a good sample, checks that no output carries
its stamp, that the rejection is counted with its reason in /diagnostics, and that a
good sample afterwards is still solved.
"""
from __future__ import annotations

import os
import signal
import time

import pytest
from builtin_interfaces.msg import Time
from ros_harness import (
    INPUTS_STATUS,
    WINCH_TOPIC,
    DomainLease,
    LiveNode,
    input_value,
    rejected_count,
    run_node_to_exit,
    stamp_from_ns,
    stamp_key,
)

from cable_winch_monitor.model.plantfile.plant import CABLE_NAMES

pytestmark = pytest.mark.timeout(60)

STALENESS = 0.5  # [s] the node's default
GOOD = (20.0, 20.0, 20.0, 20.0)
ERROR_LEVEL, WARN_LEVEL = 2, 1


@pytest.fixture(scope="module")
def live():
    node = LiveNode({"diagnostics_period": 0.2})
    yield node
    assert node.close() == 0, "winch_monitor did not exit cleanly on SIGINT"


def current_diagnostics(live) -> dict:
    return live.client.diagnostics(lambda s: True, "any status")


def assert_rejected(live, stamp, reason: str, count: int, before: dict, text: str) -> None:
    """No output for `stamp`; /diagnostics counts `count` more rejections for `reason` and quotes `text`;
    the inputs status warns (or errs); a good sample afterwards is solved."""
    expected = rejected_count(before, reason) + count
    statuses = live.client.diagnostics(lambda s: rejected_count(s, reason) >= expected,
                                       f"{expected} rejections for '{reason}'")
    assert rejected_count(statuses, reason) == expected
    assert text in input_value(statuses, "last rejection", ""), input_value(statuses, "last rejection", "")
    level, message, _ = statuses[INPUTS_STATUS]
    assert level >= WARN_LEVEL and "inputs rejected" in message, message
    good = live.client.solve(GOOD)
    assert good.pose is not None
    assert not any(live.client.outputs_with_stamp(stamp).values()), "an output for the bad sample"
    live.process.assert_alive()


@pytest.mark.parametrize("value, text", [(float("nan"), "cable_1 = nan"), (float("inf"), "cable_1 = inf"),
                                         (-20.0, "cable_1 = -20.0"), (0.0, "cable_1 = 0.0")])
def test_bad_length_is_rejected(live, value, text):
    live.client.solve(GOOD)
    before = current_diagnostics(live)
    stamp = live.client.publish((value, 20.0, 20.0, 20.0))
    assert_rejected(live, stamp, "bad length", 1, before, f"bad length: {text}")


@pytest.mark.parametrize("topic", [None, 3], ids=["merged-topic", "winch-3-topic"])
def test_a_far_future_stamp_costs_one_message_not_the_cable(live, topic):
    """sec = 2^31 - 1 used to block the cable until restart; now it is refused and the next samples are solved."""
    live.client.solve(GOOD)
    before = current_diagnostics(live)
    far = Time(sec=2 ** 31 - 1, nanosec=0)
    if topic is None:
        live.client.publish((20.3, 20.1, 20.5, 20.2), stamp=far)
    else:
        live.client.publish((20.5,), names=("cable_3",), stamp=far, topic=topic)
    source = WINCH_TOPIC if topic is None else f"/winch_{topic}/joint_states"
    reason = "stamp ahead of the clock"
    expected = rejected_count(before, reason, source) + 1
    statuses = live.client.diagnostics(lambda s: rejected_count(s, reason, source) >= expected,
                                       f"{expected} rejections for '{reason}' on {source}")
    assert rejected_count(statuses, reason, source) == expected
    assert "stamp ahead of the clock: cable_" in input_value(statuses, "last rejection", "")
    assert not any(live.client.outputs_with_stamp(far).values()), "an output for the bad sample"
    for k in range(1, 4):  # cable 3 follows its winch: not frozen at the length before the bad stamp
        length = 20.0 + 0.01 * k
        if topic is None:
            out = live.client.solve((20.0, 20.0, length, 20.0))
            assert out.pose is not None and out.tension.cables[2].length == pytest.approx(length, abs=1e-9)
        else:  # the two topics' messages may arrive in either order: the later one completes the sample
            stamps = {stamp_key(live.client.publish((20.0, 20.0, 20.0), names=("cable_1", "cable_2", "cable_4"))),
                      stamp_key(live.client.publish((length,), names=("cable_3",), topic=topic))}
            live.client.collectors["tension"].wait_for(
                lambda m, stamps=stamps, length=length: stamp_key(m.header.stamp) in stamps
                and abs(m.cables[2].length - length) < 1e-9,
                f"a sample with winch 3's new length {length} m")


def test_a_message_without_a_cable_name_is_rejected(live):
    live.client.solve(GOOD)
    before = current_diagnostics(live)
    stamp = live.client.publish((20.0,), names=("winch_9",))
    assert_rejected(live, stamp, "no cable in message", 1, before, "no cable in message: 'winch_9'")


def test_unknown_names_are_ignored_and_counted(live):
    """Other joints of a winch are ignored: the cables beside them are used, the names counted."""
    live.client.solve(GOOD)
    before = current_diagnostics(live)
    stamp = live.client.stamps.next(advance=STALENESS + 0.1)  # cable_4's last reading is now stale
    live.client.publish(GOOD[:3] + (1.0,), names=("cable_1", "cable_2", "cable_3", "winch_9"), stamp=stamp)
    ignored = int(input_value(before, "ignored name 'winch_9'")) + 1
    statuses = live.client.diagnostics(lambda s: int(input_value(s, "ignored name 'winch_9'")) == ignored,
                                       f"{ignored} ignored names 'winch_9'")
    assert "stale: cable_4" in input_value(statuses, "waiting", "")
    assert live.client.solve(GOOD).pose is not None
    assert not any(live.client.outputs_with_stamp(stamp).values()), "a pose without cable_4"


def test_duplicate_names_are_rejected(live):
    before = current_diagnostics(live)
    stamp = live.client.publish(GOOD, names=("cable_1", "cable_1", "cable_2", "cable_3"))
    assert_rejected(live, stamp, "duplicate cable names", 1, before, "duplicate cable names: cable_1")


def test_arrays_that_do_not_match_the_names_are_rejected(live):
    before = current_diagnostics(live)
    stamp = live.client.publish(GOOD[:3], names=CABLE_NAMES)
    assert_rejected(live, stamp, "malformed message", 1, before, "3 positions for 4 names")


def test_stamps_going_backwards_are_rejected(live):
    newest = live.client.solve(GOOD).tension.header.stamp
    before = current_diagnostics(live)
    older = stamp_from_ns(newest.sec * 1_000_000_000 + newest.nanosec - 50_000_000)
    live.client.publish((20.1, 20.1, 20.1, 20.1), stamp=older)
    assert_rejected(live, older, "stamp not increasing", 1, before, "stamp not increasing: cable_1")


def solver_value(statuses: dict, key: str) -> int:
    return int(statuses["winch_monitor: solver"][2][key])


def test_a_burst_of_1000_messages_in_one_second_is_accounted_for(live):
    """900 good samples and 100 without a cable name, paced at 1 ms: every one is used, rejected, or counted
    as lost before the node (its queue keeps 50 ms: it overflows only when the node is starved of CPU); every
    complete sample is solved or counted as skipped for a newer one."""
    live.client.solve(GOOD)
    before = current_diagnostics(live)
    messages = int(input_value(before, f"{WINCH_TOPIC} messages"))
    used = int(input_value(before, f"{WINCH_TOPIC} used"))
    lost = solver_value(before, "winch messages lost before the node")
    start = time.monotonic()
    for k in range(1000):
        if k % 10 == 9:
            live.client.publish((20.0,), names=("cable_9",))
        else:  # a platform being lowered at 0.1 m/s
            payout = 20.0 + 1e-4 * k
            live.client.publish((payout, payout + 0.001, payout - 0.001, payout))
        if k % 10 == 9:  # 10 messages every 10 ms
            time.sleep(max(0.0, start + (k + 1) * 1e-3 - time.monotonic()))
    assert time.monotonic() - start < 1.5, "the burst took too long to send"
    statuses = live.client.diagnostics(
        lambda s: int(input_value(s, f"{WINCH_TOPIC} messages")) + solver_value(s, "winch messages lost before the node")
        >= messages + lost + 1000, "all 1,000 burst messages counted", timeout=10.0)
    arrived = int(input_value(statuses, f"{WINCH_TOPIC} messages")) - messages
    assert arrived + solver_value(statuses, "winch messages lost before the node") - lost == 1000
    good = int(input_value(statuses, f"{WINCH_TOPIC} used")) - used
    bad = rejected_count(statuses, "no cable in message") - rejected_count(before, "no cable in message")
    assert good + bad == arrived and good <= 900 and bad <= 100
    assert arrived >= 900, "more than a tenth of the burst lost"
    complete = solver_value(statuses, "complete samples")
    assert complete == (solver_value(statuses, "samples") + solver_value(statuses, "skipped (behind by more than the backlog)")
                        + solver_value(statuses, "waiting"))
    assert live.client.solve(GOOD).pose is not None
    live.process.assert_alive()


def test_winches_that_stop_reporting_are_stale(live):
    live.client.solve(GOOD)
    statuses = live.client.diagnostics(lambda s: s[INPUTS_STATUS][0] == ERROR_LEVEL, "inputs in ERROR",
                                       timeout=STALENESS + 2.0)
    message = statuses[INPUTS_STATUS][1]
    assert all(f"{name} (" in message for name in CABLE_NAMES) and "stale" in message, message
    assert live.client.solve(GOOD).pose is not None


def test_a_missing_winch_gives_no_pose_and_an_error_naming_it():
    """A node that has only ever heard of three cables (its own process: the shared one has seen all four),
    started without any argument: it monitors the bundled plant with the default parameters."""
    node = LiveNode(params=None, params_file=None, warm_up=False)
    try:
        stamps = [node.client.publish(GOOD[:3], names=CABLE_NAMES[:3]) for _ in range(5)]
        statuses = node.client.diagnostics(lambda s: int(input_value(s, f"{WINCH_TOPIC} used")) == 5,
                                           "the five three-cable samples used")
        level, message, values = statuses[INPUTS_STATUS]
        assert level == ERROR_LEVEL and "missing: cable_4" in message, message
        assert values["cable_4 last stamp"] == "never" and values["waiting"] == "waiting for cable_4"
        assert node.client.collectors["pose"].count() == 0 and node.client.collectors["tension"].count() == 0
        assert node.client.solve(GOOD).pose is not None, "a complete sample afterwards is solved"
        assert not any(node.client.outputs_with_stamp(stamps[-1]).values())
    finally:
        assert node.close() == 0


@pytest.mark.parametrize("text, words", [
    ("plant:\n  geometry: {a: 2.0, b: 2.5, h: 10.0, k1: 0.25, k2: 0.2}\n  g: 9.8\n", "missing key 'plant.mass'"),
    ("plant: [a, b\n  mass: {\n", "not valid YAML"),
    ("plant:\n  geometry: {a: 2.0, b: two, h: 10.0, k1: 0.25, k2: 0.2}\n  mass: 1.0e4\n  g: 9.8\n",
     "'plant.geometry.b' must be a number"),
], ids=["missing-mass", "not-yaml", "bad-number"])
def test_an_unusable_plant_file_stops_the_node_with_a_message_naming_the_key(tmp_path, text, words):
    plant_file = tmp_path / "plant.yaml"
    plant_file.write_text(text)
    lease = DomainLease()
    try:
        result = run_node_to_exit(lease.domain_id, {"plant_file": plant_file})
    finally:
        lease.release()
    assert result.returncode != 0
    assert words in result.stderr and str(plant_file) in result.stderr, result.stderr
    assert "Traceback" not in result.stderr + result.stdout


def test_sigusr1_writes_every_threads_stack_to_the_log_and_the_node_goes_on(live):
    """A node that seems stuck, or does not end on SIGINT, tells where it is: SIGUSR1 writes each thread's
    Python stack to its standard error (the log the harness keeps), and the node keeps solving."""
    before = live.process.output().count("Thread 0x")
    os.kill(live.process.pid, signal.SIGUSR1)
    deadline = time.monotonic() + 10.0
    while live.process.output().count("Thread 0x") <= before and time.monotonic() < deadline:
        time.sleep(0.05)
    written = live.process.output()
    assert written.count("Thread 0x") > before, written[-2000:]
    stacks = written.split("Thread 0x", before + 1)[-1]  # what this signal had written
    assert " in _work" in stacks, "the solver thread's stack"
    assert " in spin" in stacks, "the executor's (main) thread's stack"
    assert live.client.solve(GOOD).pose is not None
    live.process.assert_alive()
