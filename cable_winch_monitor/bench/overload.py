"""The winch_monitor node under overload: 1 kHz of winch samples for 10 s over loopback DDS.

The node must never fall behind: it solves the complete samples waiting together and
counts those more than its backlog behind the newest, dropped (live.scheduler). Prints the input rate, the solved rate,
the skipped count, the pose latency p50/p99 (target: p99 < 50 ms) and whether every
input was either solved or counted as skipped, from the node's own /diagnostics. Not a
test: run

    .venv/bin/python -m cable_winch_monitor.bench.overload [--rate 1000] [--seconds 10]
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .node_latency import Probe, connect, cpu_seconds, lowering, percentiles, publish_paced, start_node, warm_up

COUNTERS = ("samples", "complete samples", "skipped (behind by more than the backlog)", "waiting", "winch messages",
            "winch messages lost before the node")
SETTLE = 1.5  # [s] after the last sample: the last solve and a /diagnostics period


class OverloadProbe(Probe):
    """The latency probe, reading the node's counters from its solver diagnostics."""

    def counters(self, timeout: float = 5.0) -> dict[str, int]:
        """The solver's counters from the next /diagnostics."""
        solver = self.next_solver_status(timeout)
        return {key: int(solver[key]) for key in COUNTERS}


def run(rate: float, seconds: float, domain_id: int) -> int:
    count = int(rate * seconds)
    readings = lowering(count, rate)
    with tempfile.TemporaryDirectory() as scratch:
        node = start_node(domain_id, "energy", Path(scratch) / "node.log")
        probe = OverloadProbe(domain_id)
        try:
            connect(probe, node, warm_up())
            time.sleep(SETTLE)
            before = probe.counters()
            probe.received.clear()
            cpu0, start = cpu_seconds(node.pid), time.monotonic()
            sent = publish_paced(probe, readings, rate)
            duration = time.monotonic() - start
            cpu = cpu_seconds(node.pid) - cpu0
            time.sleep(SETTLE)
            after = probe.counters()
            times = probe.node_times()
        finally:
            probe.close()
            node.send_signal(signal.SIGINT)
            node.wait(timeout=10)
    delta = {key: after[key] - before[key] for key in COUNTERS}
    latency = np.array([(probe.received[key] - at) / 1e6 for key, at in sent.items() if key in probe.received])
    solved, skipped = delta["samples"], delta["skipped (behind by more than the backlog)"]
    lost = delta["winch messages lost before the node"]
    accounted = (delta["complete samples"] == solved + skipped + after["waiting"] - before["waiting"]
                 and delta["winch messages"] == delta["complete samples"] and delta["winch messages"] + lost == count)
    print(f"winch_monitor under overload: {count} samples at {rate:g} Hz for {seconds:g} s over loopback DDS "
          f"(energy solver, lowering, all four cables per message)")
    print(f"  input rate          {count / duration:.0f} Hz sent, {delta['complete samples'] / duration:.0f} Hz "
          f"complete samples merged by the node ({delta['complete samples']} of {count})")
    print(f"  solved rate         {solved / duration:.0f} Hz ({solved} samples solved, {latency.size} poses received)")
    print(f"  lost before the node {lost} (publication sequence gaps: the queue overflowed)")
    print(f"  skipped             {skipped} ({100.0 * skipped / max(count, 1):.1f} %: more than the backlog behind)")
    print(f"  pose latency        {percentiles(latency)}  (target p99 < 50 ms)")
    print(f"  accounted for       {'every input solved, or counted as skipped or lost' if accounted else 'NO: ' + str(delta)}")
    print(f"  node CPU share      {100.0 * cpu / duration:.1f} % of one core")
    for name, value in times.items():
        print(f"  in the node: {name}: {value}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1000.0, help="winch samples per second")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--domain-id", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "92")))
    args = parser.parse_args(argv)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return run(args.rate, args.seconds, args.domain_id)


if __name__ == "__main__":
    sys.exit(main())
