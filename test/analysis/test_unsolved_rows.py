"""Rows the model cannot solve are said, with why: compare names them beside its scores (not every channel at
the 30-sigma penalty and "nan sigma"), diagnose refuses a bag whose held-out rows it cannot solve."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from simbags import assert_clean, run_cli

from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.paths import demo_bag

FROZEN = "/winch_3/joint_states"


def frozen_encoder(folder: Path, seconds: float) -> Path:
    """The first `seconds` of the bundled recording with winch 3's encoder stuck at its first reading: the
    platform soon hangs from cable 3 alone (single cable: no pose)."""
    out = folder / "frozen_encoder"
    first = start = None
    with BagWriter(out) as writer:
        for item in BagReader(demo_bag()):
            start = item.log_time if start is None else start
            if item.log_time > start + seconds * 1e9:
                break
            if item.topic != FROZEN:
                writer.write_raw(item.topic, item.msgtype, item.log_time, item.data)
                continue
            message = item.message
            first = np.array(message.position) if first is None else first
            message.position = first.copy()
            writer.write(item.topic, item.msgtype, item.log_time, message)
    return out


def test_compare_says_which_rows_it_could_not_solve(tmp_path):
    result = run_cli("compare", frozen_encoder(tmp_path, 12.0), "--json", tmp_path / "compare.json")
    assert_clean(result, 0)
    assert "nan sigma" not in result.stdout
    line = next(line for line in result.stdout.splitlines() if line.startswith("not solved: "))
    rows = int(line.split()[2])
    assert rows > 200 and "of 620 rows: single cable 3: pose indeterminate" in line
    assert f"{rows} rows not solved" in result.stdout  # in the failure region's description
    report = json.loads((tmp_path / "compare.json").read_text())
    assert report["unsolved"] == {"rows": rows, "reasons": {"single cable 3: pose indeterminate": rows}}


def test_diagnose_refuses_held_out_rows_it_cannot_solve(tmp_path):
    result = run_cli("diagnose", frozen_encoder(tmp_path, 25.0), "--budget", "60")
    assert_clean(result, 2)
    assert result.stderr.count("\n") == 1
    assert "the model could not solve any held-out row (208 of 208 rows: single cable 3: pose indeterminate " \
        "(208)): nothing to score a candidate on" in result.stderr
