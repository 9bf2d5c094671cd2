"""Linear algebra on stacks of small matrices, lean for a stack of one.

numpy's stacked routines cost microseconds per call whatever the size, which dominates a
control loop's step on one 3×3 state; LAPACK's own routines (through SciPy) cost a fraction of
that. Each function takes stacks, (k, n, n) and (k, n, p), and answers for every k with the same
mathematics, so that batches and single states run one code path.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgesv, dpotrf, dpotrs


def solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X = A⁻¹ B for stacks A (k, n, n), B (k, n, p); `numpy.linalg.LinAlgError` where A is
    singular."""
    if len(A) == 1:
        _, _, X, info = dgesv(A[0], B[0])
        if info > 0:
            raise np.linalg.LinAlgError("Singular matrix")
        return X[None]
    return np.linalg.solve(A, B)


def solve_conditioned(G: np.ndarray, B: np.ndarray, ratio: float) -> np.ndarray | None:
    """X = G⁻¹ B for symmetric positive definite stacks G (k, m, m), B (k, m, p), where every G
    is provably conditioned: det G ≥ ratio · (tr G)^m. Otherwise None.

    det G / (tr G)^m ≤ σ_min / σ_max (det G = Π σ_i ≤ σ_min σ_max^(m−1), σ_max ≤ tr G), so a G
    that passes has σ_min / σ_max ≥ ratio. For one G the Cholesky factor gives the determinant
    and the solve at once.
    """
    m = G.shape[-1]
    if len(G) == 1:
        factor, info = dpotrf(G[0])
        if info:
            return None
        determinant = math.prod(factor.diagonal().tolist()) ** 2
        if determinant < ratio * math.fsum(G[0].diagonal().tolist()) ** m:
            return None
        return dpotrs(factor, B[0])[0][None]
    with np.errstate(invalid="ignore", over="ignore"):
        conditioned = np.linalg.det(G) >= ratio * np.trace(G, axis1=1, axis2=2) ** m
    if not np.all(conditioned):
        return None
    return np.linalg.solve(G, B)
