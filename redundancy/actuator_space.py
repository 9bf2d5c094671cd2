"""Hydraulic (actuator) coordinates at a state: x, A, Ȧ, J_H, M_H, N_H and forces F_H.

With A = ∂x/∂q (Eq. 11), ẋ = A q̇ and ẍ = A q̈ + Ȧ q̇ (Eq. 12), the joint-space model
M q̈ + N = τ (Eq. 18, N = V + G) with τ = Aᵀ F (virtual work; the paper writes τ = A F, Eq. 15,
because its A is diagonal) becomes, in actuator coordinates (Eqs. 16, 20-23, 25),

    J_H = J A⁻¹                   ẏ = J_H ẋ
    M_H = A⁻ᵀ M A⁻¹               N_H = A⁻ᵀ N − M_H Ȧ A⁻¹ ẋ
    F_H = M_H ẍ + N_H

A is never inverted: every product with A⁻¹ is a linear solve. A is singular where a cylinder's
torque arm vanishes (its line passes through the joint); there `SingularConfigurationError`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from redundancy.errors import InvalidInputError, SingularConfigurationError
from redundancy.robot import Robot

SINGULAR_TOLERANCE = 1e-9


def solve_right(B: np.ndarray, A: np.ndarray) -> np.ndarray:
    """B A⁻¹ for stacks B (k, p, n), A (k, n, n)."""
    return np.swapaxes(np.linalg.solve(np.swapaxes(A, 1, 2), np.swapaxes(B, 1, 2)), 1, 2)


def invertibility(A: np.ndarray) -> np.ndarray:
    """σ_min / σ_max of each A (k, n, n), (k,): 1 for an orthogonal A, 0 for a singular one."""
    singular_values = np.linalg.svd(A, compute_uv=False)
    return singular_values[:, -1] / np.maximum(singular_values[:, 0], np.finfo(float).tiny)


def singular(A: np.ndarray, tolerance: float = SINGULAR_TOLERANCE) -> np.ndarray:
    """Where `invertibility` (k,) falls below ``tolerance`` or A is not finite, (k,) bool.

    |det A| / ‖A‖_F^n bounds σ_min / σ_max from below (|det A| = Π σ_i ≤ σ_min σ_max^(n−1) and
    σ_max ≤ ‖A‖_F), so the singular values are computed only where that bound is not enough.
    """
    n = A.shape[-1]
    frobenius = np.einsum("kij,kij->k", A, A)
    with np.errstate(invalid="ignore", over="ignore"):
        settled = np.linalg.det(A) ** 2 >= tolerance**2 * frobenius**n
    found = np.zeros(len(A), dtype=bool)
    rows = np.flatnonzero(~settled)
    if rows.size:
        finite = np.all(np.isfinite(A[rows]), axis=(1, 2))
        found[rows] = ~finite
        found[rows[finite]] = invertibility(A[rows[finite]]) < tolerance
    return found


def check_invertible(A: np.ndarray, q: np.ndarray, names: list[str]) -> None:
    """Raise `SingularConfigurationError` where A is singular to working precision."""
    bad = np.flatnonzero(singular(A))
    if bad.size:
        i = bad[0]
        weakest = names[int(np.argmin(np.linalg.norm(A[i], axis=1)))]
        raise SingularConfigurationError(
            f"actuator Jacobian A is singular at q = {np.round(q[i], 6).tolist()} "
            f"(weakest: actuator {weakest!r}); the actuators cannot move the joints there"
        )


@dataclass(frozen=True)
class ActuatorSpace:
    """The robot in actuator coordinates at a batch of k states (batch axis always first).

    q, v (k, n) joint state; x, x_dot (k, n) actuator state (m, m/s); y (k, m) task point (m);
    A, A_dot (k, n, n); J, J_H (k, m, n). The dynamic terms M_H (k, n, n, kg) and N_H (k, n, N)
    are computed when first read. Without velocities the state is at rest: Ȧ = 0, N_H = A⁻ᵀ G.
    """

    robot: Robot = field(repr=False)
    q: np.ndarray
    v: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    y: np.ndarray
    A: np.ndarray
    A_dot: np.ndarray
    J: np.ndarray
    J_H: np.ndarray

    @cached_property
    def M_H(self) -> np.ndarray:
        """M_H = A⁻ᵀ M A⁻¹ (Eq. 22), symmetric positive definite."""
        A_T = np.swapaxes(self.A, 1, 2)
        half = np.linalg.solve(A_T, self.robot.mass_matrices(self.q))  # A⁻ᵀ M
        M_H = np.linalg.solve(A_T, np.swapaxes(half, 1, 2))  # A⁻ᵀ (A⁻ᵀ M)ᵀ = A⁻ᵀ M A⁻¹
        return (M_H + np.swapaxes(M_H, 1, 2)) / 2

    @cached_property
    def N_H(self) -> np.ndarray:
        """N_H = A⁻ᵀ N − M_H Ȧ A⁻¹ ẋ (Eq. 23), with A⁻¹ ẋ = q̇."""
        N = self.robot.nonlinear(self.q, self.v)
        a_dot_v = (self.A_dot @ self.v[:, :, None])[:, :, 0]
        return (
            np.linalg.solve(np.swapaxes(self.A, 1, 2), N[:, :, None])[:, :, 0]
            - (self.M_H @ a_dot_v[:, :, None])[:, :, 0]
        )

    def forces(self, x_ddot: np.ndarray) -> np.ndarray:
        """Actuator forces F_H = M_H ẍ + N_H (Eq. 21), (k, n) in N, for x_ddot (k, n)."""
        return (self.M_H @ np.asarray(x_ddot)[:, :, None])[:, :, 0] + self.N_H


def actuator_space(robot: Robot, q, v=None, check: bool = True) -> ActuatorSpace:
    """`ActuatorSpace` at q of shape (n,) or (k, n) and joint velocities v like q (default rest).

    One state comes back as a batch of one. ``check`` raises `SingularConfigurationError` where
    A is singular; callers that handle singular states themselves (the simulation) turn it off.
    """
    qb = robot.configuration(q)
    vb = None if v is None else robot.configuration(v, "v")
    if vb is not None and vb.shape != qb.shape:
        raise InvalidInputError(f"v has shape {vb.shape}; q has {qb.shape}")
    kinematics = robot.kinematics(qb, vb)
    x, A = robot.actuators.evaluate(kinematics)
    if check:
        check_invertible(A, qb, robot.actuators.names)
    task = robot.task(kinematics)
    if vb is None:
        vb, A_dot = np.zeros_like(qb), np.zeros_like(A)
    else:
        A_dot = robot.actuators.rate(kinematics)
    return ActuatorSpace(
        robot=robot,
        q=qb,
        v=vb,
        x=x,
        x_dot=(A @ vb[:, :, None])[:, :, 0],
        y=task.position,
        A=A,
        A_dot=A_dot,
        J=task.jacobian,
        J_H=solve_right(task.jacobian, A),
    )
