"""Linear algebra on stacks of small matrices: the compiled core's solve,
X = A⁻¹ B for A (k, n, n) and B (k, n, p) or (k, n), `numpy.linalg.LinAlgError` where A is
singular (a pivot of its LU factors exactly zero, as LAPACK's)."""

from redundancy._core import solve

__all__ = ["solve"]
