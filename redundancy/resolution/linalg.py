"""Linear algebra on stacks of small matrices, lean for a stack of one.

numpy's stacked routines cost microseconds per call whatever the size, which dominates a
control loop's step on one 3×3 state; LAPACK's own routines (through SciPy) cost a fraction of
that. Each function takes stacks, (k, n, n) and (k, n, p), and answers for every k with the same
mathematics, so that batches and single states run one code path.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgesv


def solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X = A⁻¹ B for stacks A (k, n, n), B (k, n, p); `numpy.linalg.LinAlgError` where A is
    singular."""
    if len(A) == 1:
        _, _, X, info = dgesv(A[0], B[0])
        if info > 0:
            raise np.linalg.LinAlgError("Singular matrix")
        return X[None]
    return np.linalg.solve(A, B)
