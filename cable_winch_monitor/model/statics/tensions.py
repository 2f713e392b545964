"""Cable tensions from the wrench balance J^T tau = F on a set of taut cables."""
from __future__ import annotations

from itertools import combinations

import numpy as np

RANK_RTOL = 1e-10
BALANCE_TOL = 1e-9  # relative residual of J^T tau = F for a subset to count as balancing


def balance_tensions(structure: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """Tensions solving structure @ tau = wrench, the least-norm non-negative one where not unique.

    Where the taut cables are redundant (four equal lengths: rank 3 for four unknowns) the
    balance leaves a family of solutions; the least-norm non-negative member is the most
    even distribution, the minimum of seed 002's Delta T (Delta T^2 = n |tau|^2 - (sum tau)^2
    and sum tau is fixed by the vertical balance). Otherwise, or where no member is
    non-negative, the least-squares solution is returned and the caller sees its residual
    and signs.
    """
    u, sigma, vt = np.linalg.svd(structure, full_matrices=True)
    rank = int(np.sum(sigma > RANK_RTOL * sigma[0])) if sigma.size else 0
    particular = vt[:rank].T @ ((u[:, :rank].T @ wrench) / sigma[:rank])
    if rank == structure.shape[1]:
        return particular
    even = least_norm_tensions(structure, wrench)
    return particular if even is None else even


def least_norm_tensions(structure: np.ndarray, wrench: np.ndarray) -> np.ndarray | None:
    """The least-norm tau >= 0 with structure @ tau = wrench, or None if there is none.

    At the optimum the positive tensions are the least-norm solution on their own columns
    (KKT), so trying every subset of columns and keeping the smallest feasible one is exact.
    """
    best: np.ndarray | None = None
    scale = float(np.linalg.norm(wrench))
    for size in range(1, structure.shape[1] + 1):
        for subset in combinations(range(structure.shape[1]), size):
            columns = structure[:, subset]
            part = np.linalg.lstsq(columns, wrench, rcond=None)[0]
            if np.linalg.norm(columns @ part - wrench) > BALANCE_TOL * scale or part.min() < -BALANCE_TOL * scale:
                continue
            tau = np.zeros(structure.shape[1])
            tau[list(subset)] = np.maximum(part, 0.0)
            if best is None or tau @ tau < best @ best:
                best = tau
    return best
