"""What the plant was doing at each measurement, winch by winch: lowering, hoisting, shifting or standing.

Each winch is paying out when its payout speed is above the conditions' DEADBAND, hauling in
when it is below -DEADBAND, still otherwise (or when it reports no speed). A row is lowering
when some winches pay out and none hauls in, hoisting when some haul in and none pays
out, shifting when some pay out while others haul in (the platform moves sideways or
tilts: its mean payout may stand still), standing when no winch moves. A stretch of time
is described by the share of each.
"""
from __future__ import annotations

import numpy as np

from ..model.conditions import DEADBAND

MOTIONS = ("lowering", "hoisting", "shifting", "standing")
LOWERING, HOISTING, SHIFTING, STANDING = range(4)


def motions(speeds: np.ndarray) -> np.ndarray:
    """Index into MOTIONS of each row of payout speeds (n, 4) [m/s]."""
    speeds = np.nan_to_num(np.asarray(speeds, dtype=float).reshape(-1, 4))
    out_ = (speeds > DEADBAND).any(axis=1)
    in_ = (speeds < -DEADBAND).any(axis=1)
    return np.select([out_ & in_, out_, in_], [SHIFTING, LOWERING, HOISTING], STANDING)


def shares(kinds: np.ndarray) -> dict[str, float]:
    """Share of rows in each motion (0..1; all zero for no rows)."""
    counts = np.bincount(np.asarray(kinds, dtype=int), minlength=len(MOTIONS))
    total = max(int(counts.sum()), 1)
    return {name: float(n) / total for name, n in zip(MOTIONS, counts)}


def describe(share: dict[str, float]) -> str:
    """'lowering 62 %, hoisting 30 %, standing 8 %' (largest first, motions that do not occur left out)."""
    present = sorted(((s, name) for name, s in share.items() if s > 0.0), reverse=True)
    return ", ".join(f"{name} {100.0 * s:.0f} %" for s, name in present) or "no motion data"
