"""Random cable lengths over a realistic shaft, for the solver tests."""
from __future__ import annotations

import numpy as np


def random_lengths(count: int, seed: int = 2002, family: str = "generic") -> np.ndarray:
    """Payouts of 5-800 m plus per-cable offsets of up to 2 m.

    generic: in equal parts log-uniform spreads (millimetres to metres), uniform spreads,
    and one cable 0.5-2 m shorter than the others (where the platform may hang from it
    alone). adjacent_equal: l1 = l2, l3 = l4 or l1 = l4, l2 = l3. plane: l1 + l3 = l2 + l4.
    """
    rng = np.random.default_rng(seed)
    kind = np.arange(count) % 3
    payout = rng.uniform(5.0, 800.0, count)
    spread = np.where(kind == 1, rng.uniform(0.0, 2.0, count), 10.0 ** rng.uniform(-3.0, np.log10(2.0), count))
    lengths = payout[:, None] + rng.uniform(0.0, 1.0, (count, 4)) * spread[:, None]
    if family == "generic":
        short = np.flatnonzero(kind == 2)
        lengths[short, rng.integers(0, 4, short.size)] -= rng.uniform(0.5, 2.0, short.size)
    elif family == "adjacent_equal":
        swap = rng.integers(0, 2, count).astype(bool)
        lengths[:, 1] = np.where(swap, lengths[:, 2], lengths[:, 0])
        lengths[:, 3] = np.where(swap, lengths[:, 0], lengths[:, 2])
    elif family == "plane":
        lengths[:, 3] = lengths[:, 0] + lengths[:, 2] - lengths[:, 1]
    else:
        raise ValueError(family)
    return lengths
