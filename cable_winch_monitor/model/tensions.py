"""Cable tensions from the wrench balance J^T tau = F on a set of taut cables."""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

RANK_RTOL = 1e-10


def balance_tensions(structure: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """Tensions tau >= 0 solving structure @ tau = wrench, the least-norm one where not unique.

    Where the taut cables are redundant (four equal lengths: rank 3 for four unknowns) the
    balance leaves a family of solutions; the least-norm non-negative member is the most
    even distribution, the minimum of seed 002's Delta T (Delta T^2 = n |tau|^2 - (sum tau)^2
    and sum tau is fixed by the vertical balance). Where the balance has no exact solution
    the least-squares one is returned and the caller sees the residual.
    """
    u, sigma, vt = np.linalg.svd(structure, full_matrices=True)
    rank = int(np.sum(sigma > RANK_RTOL * sigma[0])) if sigma.size else 0
    particular = vt[:rank].T @ ((u[:, :rank].T @ wrench) / sigma[:rank])
    null = vt[rank:].T
    return particular if null.shape[1] == 0 else _least_norm_nonnegative(particular, null)


def _least_norm_nonnegative(particular: np.ndarray, null: np.ndarray) -> np.ndarray:
    """min |p + N t| subject to p + N t >= 0: the particular solution is already least-norm, so
    t = 0 is optimal when feasible; otherwise a small QP over t."""
    if particular.min() >= 0.0:
        return particular
    if null.shape[1] == 1:
        n = null[:, 0]
        lower = max([(-particular[i]) / n[i] for i in range(n.size) if n[i] > 1e-14], default=-np.inf)
        upper = min([(-particular[i]) / n[i] for i in range(n.size) if n[i] < -1e-14], default=np.inf)
        t = float(np.clip(0.0, lower, upper)) if lower <= upper else lower
        return np.maximum(particular + t * n, 0.0)
    result = minimize(lambda t: float(np.sum((particular + null @ t) ** 2)), np.zeros(null.shape[1]),
                      jac=lambda t: 2.0 * null.T @ (particular + null @ t), method="SLSQP",
                      constraints={"type": "ineq", "fun": lambda t: particular + null @ t, "jac": lambda t: null})
    return np.maximum(particular + null @ result.x, 0.0)
