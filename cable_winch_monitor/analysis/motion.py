"""What the plant was doing at each measurement: lowering, hoisting or standing, from the winches' payout speeds.

A row is lowering when the mean payout speed of the four winches is at least STOPPED
(ropes paid out), hoisting when it is at most -STOPPED, standing otherwise (or when no
winch reports a speed). A stretch of time is described by the share of each.
"""
from __future__ import annotations

import numpy as np

MOTIONS = ("lowering", "hoisting", "standing")
LOWERING, HOISTING, STANDING = range(3)
STOPPED = 0.02  # [m/s] mean payout speed below which the plant is standing


def motions(speeds: np.ndarray) -> np.ndarray:
    """Index into MOTIONS of each row of payout speeds (n, 4) [m/s]."""
    speeds = np.asarray(speeds, dtype=float).reshape(-1, 4)
    reported = np.isfinite(speeds).any(axis=1)
    mean = np.nansum(speeds, axis=1) / np.maximum(np.isfinite(speeds).sum(axis=1), 1)
    out = np.full(len(speeds), STANDING)
    out[reported & (mean >= STOPPED)] = LOWERING
    out[reported & (mean <= -STOPPED)] = HOISTING
    return out


def shares(kinds: np.ndarray) -> dict[str, float]:
    """Share of rows in each motion (0..1; all zero for no rows)."""
    counts = np.bincount(np.asarray(kinds, dtype=int), minlength=len(MOTIONS))
    total = max(int(counts.sum()), 1)
    return {name: float(n) / total for name, n in zip(MOTIONS, counts)}


def describe(share: dict[str, float]) -> str:
    """'lowering 62 %, hoisting 30 %, standing 8 %' (largest first, motions that do not occur left out)."""
    present = sorted(((s, name) for name, s in share.items() if s > 0.0), reverse=True)
    return ", ".join(f"{name} {100.0 * s:.0f} %" for s, name in present) or "no motion data"
