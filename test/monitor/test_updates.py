"""The node's update process never keeps a stop waiting: closed, it ends with its update under way."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

HELPERS = Path(__file__).parents[1] / "helpers"
# A process of its own, as the node is: an update that would take ten minutes in the update process is under
# way when the update process is closed; the update is then awaited, and the process exits.
SCRIPT = """
import sys, time
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.monitor.updates import UpdateProcess
from slow_update import SlowInItsProcess

plant = load_plant()
process = UpdateProcess(plant)
pending = process.submit(SlowInItsProcess(600.0))
deadline = time.monotonic() + 60.0
while not process.process_ids() and time.monotonic() < deadline:
    time.sleep(0.05)
time.sleep(0.5)  # the update under way in the process
closed = time.monotonic()
process.close()
answer = pending.result(PlantModel.from_plant(plant))
later = process.submit(SlowInItsProcess(600.0)).result(PlantModel.from_plant(plant))
print(process.process_ids()[0], time.monotonic() - closed, answer, later, process.losses, sep="|")
"""


def test_a_closed_update_process_ends_with_its_update_and_the_update_is_worked_out_where_awaited():
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join([str(HELPERS), os.environ.get("PYTHONPATH", "")])})
    took = time.monotonic() - started
    assert done.returncode == 0, done.stderr
    pid, after_close, answer, later, losses = done.stdout.strip().split("|")
    assert answer == later == "worked out where it was awaited"
    assert float(after_close) < 5.0, "the update was not awaited from the process once it was closed"
    assert took < 60.0, f"the exit waited for the update under way ({took:.0f} s)"
    assert losses == "0", "a process ended by close is not a lost one"
    for _ in range(50):  # the process is gone (reaped once its forkserver ended with the script)
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        pytest.fail(f"the update process {pid} still runs")
