"""How right the monitor's safety outputs were on a simulated recording, judged against its truth.

A replayed (or recorded) output bag's wall clearance, alarm levels and slack flags against
the simulator's ground truth (`sim`: its own root-found equilibrium), sample by sample:

- clearance error: the published clearance minus the true one;
- CRITICAL: the samples truly within the CRITICAL margin published CRITICAL or worse, and the
  samples published CRITICAL or worse while truly more than FALSE_MARGIN outside it;
- slack flags: each rope of each sample, slack where it truly carries less than SLACK [N] at
  the platform and taut where more than TAUT [N] (those between not scored);
- what the alarms were based on (the reason's basis).
"""
from __future__ import annotations

import csv
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..bagio.reader import BagReader
from ..messages.outputs import ALARM, OUTPUT_TYPES, TENSION
from ..monitor.alarm import AlarmLevel, AlarmPolicy
from ..sim.simulate import TRUTH_FILE

SLACK, TAUT = 100.0, 1500.0  # [N] at the platform: truly slack below, truly taut above
FALSE_MARGIN = 0.02  # [m] outside the CRITICAL margin by more than this, a CRITICAL alarm is a false one


@dataclass
class SafetyScore:
    """The safety outputs of one replay against the truth."""

    samples: int = 0
    clearance_errors: list[float] = field(default_factory=list)  # [m] published minus true
    critical: int = 0          # samples truly within the CRITICAL margin
    critical_raised: int = 0   # of those, published CRITICAL or worse
    false_critical: int = 0    # published CRITICAL or worse while truly more than FALSE_MARGIN outside it
    ropes: int = 0             # rope-samples scored (truly slack or truly taut)
    ropes_right: int = 0       # of those, flagged as they truly are
    basis: Counter[str] = field(default_factory=Counter)

    @property
    def clearance_p99(self) -> float:
        return float(np.percentile(np.abs(self.clearance_errors), 99)) if self.clearance_errors else float("nan")

    @property
    def recall(self) -> float:
        return self.critical_raised / self.critical if self.critical else float("nan")

    @property
    def false_share(self) -> float:
        return self.false_critical / self.samples if self.samples else float("nan")

    @property
    def slack_right(self) -> float:
        return self.ropes_right / self.ropes if self.ropes else float("nan")

    def format(self) -> str:
        basis = ", ".join(f"{text} {n}" for text, n in self.basis.most_common())
        return (f"clearance error p99 {1e3 * self.clearance_p99:.1f} mm; CRITICAL {self.critical_raised} of "
                f"{self.critical} samples within the margin ({100 * self.recall:.1f} %), {self.false_critical} "
                f"false ({100 * self.false_share:.2f} % of {self.samples}); slack flags right "
                f"{100 * self.slack_right:.2f} % of {self.ropes} rope-samples; based on: {basis}")


def _truth(bag: Path) -> dict[int, dict[str, str]]:
    """The truth at each winch sample [ns] (every sensor stream has a row; the winches' are the samples)."""
    with (bag / TRUTH_FILE).open() as file:
        return {int(round(float(row["time"]) * 1e9)): row for row in csv.DictReader(file)
                if row["stream"] == "joint_states" or row["stream"].startswith("winch_")}


def _stamp(message: Any) -> int:
    stamp = message.header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def basis_of(reason: str) -> str:
    """What an alarm's reason says its clearance is based on, without its numbers."""
    found = re.search(r"\((tilt measured[^;)]*|model only(?: \(no tilt measured\))?|the model's)", reason)
    return found.group(1) if found else "none given"


def score(out: Path, bag: Path, policy: AlarmPolicy | None = None, start: float = -np.inf) -> SafetyScore:
    """The safety outputs of the output bag `out` against the truth of the simulated recording `bag`, over its
    samples stamped `start` [s] or later."""
    policy = policy or AlarmPolicy()
    truth = _truth(Path(bag))
    alarms: dict[int, Any] = {}  # decoded messages by their stamp [ns]
    tensions: dict[int, Any] = {}
    for item in BagReader(out, {ALARM: OUTPUT_TYPES[ALARM], TENSION: OUTPUT_TYPES[TENSION]}):
        (alarms if item.topic == ALARM else tensions)[_stamp(item.message)] = item.message
    result = SafetyScore()
    for stamp, alarm in sorted(alarms.items()):
        row = truth.get(stamp)
        if row is None or stamp not in tensions or stamp < start * 1e9:
            continue
        result.samples += 1
        result.basis[basis_of(alarm.reason)] += 1
        clearance = float(row["clearance"])
        if np.isfinite(alarm.clearance) and np.isfinite(clearance):
            result.clearance_errors.append(alarm.clearance - clearance)
        raised = alarm.level >= AlarmLevel.CRITICAL
        if clearance <= policy.critical_margin:
            result.critical += 1
            result.critical_raised += int(raised)
        elif clearance > policy.critical_margin + FALSE_MARGIN:
            result.false_critical += int(raised)
        for i, cable in enumerate(tensions[stamp].cables):
            true = float(row[f"tension_{i + 1}"])
            if true < SLACK or true > TAUT:
                result.ropes += 1
                result.ropes_right += int(bool(cable.taut) == (true > TAUT))
    return result
