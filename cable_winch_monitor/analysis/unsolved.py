"""Rows the model gives no pose: counted by why, said beside every score, refused where no row has one.

A row without a solved pose (a single cable holding the platform, no equilibrium, lengths
that are not lengths, an effect's hook failing) has no prediction: the scores count its
measurements as FAILED_PENALTY-sigma misses (analysis.evaluate), so that a fit cannot gain
by making rows unsolvable. Where most rows are so, the scores are the penalty, not the
model's error, and the report says why; where none is solved, nothing is compared.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from ..bagio.reader import BagError
from ..model.statics.result import Solution

SHOWN = 3  # reasons named in a report line


def unsolved(solutions: Sequence[Solution]) -> Counter[str]:
    """Rows without a solved pose, counted by why (Solution.failure)."""
    return Counter(s.failure for s in solutions if not s.ok)


def describe(reasons: Counter[str], rows: int) -> str:
    """'N of M rows: reason (n), ...' (the most frequent reasons first)."""
    shown = ", ".join(f"{reason} ({count})" for reason, count in reasons.most_common(SHOWN))
    more = f", {len(reasons) - SHOWN} other reasons" if len(reasons) > SHOWN else ""
    return f"{sum(reasons.values())} of {rows} rows: {shown}{more}"


def require_solved(bag: str, solutions: Sequence[Solution], what: str, rows: str = "row") -> Counter[str]:
    """The unsolved rows by reason; BagError where the model solves none of them (nothing to `what`)."""
    reasons = unsolved(solutions)
    if solutions and sum(reasons.values()) == len(solutions):
        raise BagError(f"{bag}: the model could not solve any {rows} ({describe(reasons, len(solutions))}): "
                       f"nothing to {what}")
    return reasons
