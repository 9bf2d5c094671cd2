"""Hydraulic (actuator) coordinates at a batch of states: the one object every consumer reads.

One Pinocchio pass (`Robot.kinematics`) gives the tracked frames; x, A = ∂x/∂q (Eqs. 10-11),
y and J = ∂y/∂q (Eqs. 6-7) are read from it, and the rest is derived when first asked for.
With ẋ = A q̇ and ẍ = A q̈ + Ȧ q̇ (Eq. 12), the joint-space model M q̈ + N = τ (Eq. 18,
N = V + G) with τ = Aᵀ F (virtual work; the paper writes τ = A F, Eq. 15, because its A is
diagonal) becomes, in actuator coordinates (Eqs. 16, 20-23, 25),

    J_H = J A⁻¹                   ẏ = J_H ẋ
    M_H = A⁻ᵀ M A⁻¹               N_H = A⁻ᵀ N − M_H Ȧ A⁻¹ ẋ
    F_H = M_H ẍ + N_H

A is never inverted: every product with A⁻¹ is a solve with A's LU factors, in the compiled core
(`redundancy._core`), which also runs the pass, the built-in actuator kinds, y, J and J_H in one
call per batch (`Robot.evaluator`); a kind or a task of your own is evaluated in Python, and the
rest derived by the same core. A is singular where a cylinder's torque arm vanishes (its line
passes through the joint); `actuator_space` then raises `SingularConfigurationError` naming the
weakest actuator, and the integrators freeze such states.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from redundancy import _core
from redundancy.errors import InvalidInputError, SingularConfigurationError
from redundancy.model.kinematics import Kinematics, join, remade, take
from redundancy.model.robot import SINGULAR_TOLERANCE as SINGULAR_TOLERANCE
from redundancy.model.robot import Robot, require_robot
from redundancy.model.schema import excerpt


def per_state(values, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``values`` as finite numbers of ``shape``, a row per state of a batch (for a batch of
    one, its row alone too); one line naming ``name`` (`InvalidInputError`) otherwise."""
    try:
        checked = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        checked = None
    if checked is not None and shape[0] == 1 and checked.shape == shape[1:]:
        checked = checked[None]
    if checked is None or checked.shape != shape or not np.isfinite(checked).all():
        shown = values.tolist() if isinstance(values, np.ndarray) else values  # on one line
        raise InvalidInputError(
            f"{name} must be finite numbers of shape {shape}, a row per state; got {excerpt(shown)}"
        )
    return checked


def singular(A: np.ndarray, tolerance: float = SINGULAR_TOLERANCE) -> np.ndarray:
    """Where σ_min / σ_max of each A (k, n, n) falls below ``tolerance`` or A is not finite,
    (k,) bool; the core bounds the ratio below by |det A| / ‖A‖_F^n (|det A| = Π σ_i ≤
    σ_min σ_max^(n−1) and σ_max ≤ ‖A‖_F) and computes the singular values only where that bound
    is not enough."""
    return _core.derive(A, np.empty((len(A), 0, A.shape[-1])), tolerance)[1]


def check_invertible(space: ActuatorSpace) -> None:
    """Raise where a state is bad: the error of the actuator the core could not evaluate there
    (a cylinder of zero length, a linkage that cannot close), else `SingularConfigurationError`
    where A is singular to working precision."""
    refused = vars(space).get("_refused")
    if refused is not None:
        state, actuator, status = refused
        space.robot.actuators.maps[actuator].refuse(space.kinematics, state, status)
    bad = np.flatnonzero(space._bad)
    if bad.size:
        i = bad[0]
        weakest = space.robot.actuators.names[int(np.argmin(np.linalg.norm(space.A[i], axis=1)))]
        raise SingularConfigurationError(
            f"actuator Jacobian A is singular at q = {np.round(space.q[i], 6).tolist()} "
            f"(weakest: actuator {weakest!r}); the actuators cannot move the joints there"
        )


@dataclass(frozen=True, eq=False)
class ActuatorSpace:
    """The robot in actuator coordinates at a batch of k states (batch axis always first).

    Read from the one Pinocchio pass: q (k, n) joints; x (k, n) strokes (m, or rad for a rotary
    actuator); A (k, n, n); y (k, m) task point (m); J (k, m, n); v (k, n) joint velocities, or
    None at rest; x_ddot (k, n) actuator accelerations where known. Derived when first read:
    x_dot, A_dot, J_H, M, M_H (kg), N_H (N), and with x_ddot F_H (N).
    """

    robot: Robot = field(repr=False)
    kinematics: Kinematics = field(repr=False)
    q: np.ndarray
    v: np.ndarray | None
    x: np.ndarray
    A: np.ndarray
    y: np.ndarray
    J: np.ndarray
    x_ddot: np.ndarray | None = None

    @cached_property
    def x_dot(self) -> np.ndarray:
        """ẋ = A q̇ (Eq. 11), (k, n); zero at rest."""
        if self.v is None:
            return np.zeros_like(self.x)
        return (self.A @ self.v[..., None])[..., 0]

    @cached_property
    def A_dot(self) -> np.ndarray:
        """Ȧ (k, n, n), so that ẍ = A q̈ + Ȧ q̇ (Eq. 12); zero at rest. Read from the same
        pass's Jacobians (`Kinematics.moving`), whenever v became known."""
        if self.v is None:
            return np.zeros_like(self.A)
        kinematics = self.kinematics
        if kinematics.jacobian_rates is None:
            kinematics = kinematics.moving(self.v)
        return self.robot.actuators.rate(kinematics)

    def _derive(self) -> np.ndarray:
        """J_H, derived in one call of the core with where A is singular; ``_bad`` kept."""
        J_H, singular_A = _core.derive(self.A, self.J, SINGULAR_TOLERANCE)
        vars(self)["_bad"] = singular_A | ~np.isfinite(self.q).all(axis=1)
        return J_H

    @cached_property
    def J_H(self) -> np.ndarray:
        """J_H = J A⁻¹ (Eqs. 16, 25), (k, m, n)."""
        return self._derive()

    @cached_property
    def _bad(self) -> np.ndarray:
        """Where A is singular to working precision (`singular`) or q is not finite, (k,)."""
        vars(self)["J_H"] = self._derive()
        return vars(self)["_bad"]

    @cached_property
    def M(self) -> np.ndarray:
        """Joint-space inertia M(q) (Eq. 18), (k, n, n), by CRBA."""
        return self.robot.mass_matrices(self.q)

    @cached_property
    def M_H(self) -> np.ndarray:
        """M_H = A⁻ᵀ M A⁻¹ (Eq. 22), symmetric positive definite."""
        return _core.inertias(self.A, self.M)

    @cached_property
    def N_H(self) -> np.ndarray:
        """N_H = A⁻ᵀ N − M_H Ȧ A⁻¹ ẋ (Eq. 23), with A⁻¹ ẋ = q̇; A⁻ᵀ G at rest."""
        v = np.zeros_like(self.q) if self.v is None else self.v
        return _core.biases(self.A, self.robot.nonlinear(self.q, v), self.M_H, self.A_dot, v)

    @cached_property
    def F_H(self) -> np.ndarray:
        """F_H = M_H ẍ + N_H (Eq. 21) (k, n) in N, at the accelerations ``x_ddot`` the states
        were given (`InvalidInputError` without them)."""
        if self.x_ddot is None:
            raise InvalidInputError("these states carry no accelerations ẍ; use forces(x_ddot)")
        return self.forces(self.x_ddot)

    def forces(self, x_ddot: np.ndarray) -> np.ndarray:
        """Actuator forces F_H = M_H ẍ + N_H (Eq. 21), (k, n) in N, for x_ddot (k, n)."""
        x_ddot = per_state(x_ddot, "x_ddot", self.x.shape)
        return (self.M_H @ x_ddot[..., None])[..., 0] + self.N_H

    def joint_velocities(self, x_dot: np.ndarray) -> np.ndarray:
        """q̇ = A⁻¹ ẋ (Eq. 11) for actuator velocities ẋ (k, n)."""
        return _core.solve(self.A, per_state(x_dot, "x_dot", self.x.shape))

    def moving(self, v: np.ndarray, x_ddot: np.ndarray | None = None) -> ActuatorSpace:
        """These states at joint velocities v (k, n), once a law has solved for them, and
        accelerations ``x_ddot`` where known: what depends on q alone (J_H, M, M_H), where
        already derived, is kept."""
        return self._kept(remade(self, v=v, x_ddot=x_ddot))

    def take(self, rows: np.ndarray) -> ActuatorSpace:
        """The states ``rows`` (indices into the batch, or a mask over it) alone."""
        rows = np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        taken: dict[str, Any] = {name: take(getattr(self, name), rows) for name in ARRAYS}
        return self._kept(remade(self, kinematics=self.kinematics.take(rows), **taken), rows)

    def _kept(self, other: ActuatorSpace, rows: np.ndarray | None = None) -> ActuatorSpace:
        """``other`` (these states, or those ``rows`` of them) with what is derived from q
        alone copied over, not derived again."""
        for name in KEPT.intersection(vars(self)):
            derived = vars(self)[name]
            vars(other)[name] = derived if rows is None else take(derived, rows)
        return other

    @classmethod
    def joined(cls, parts: list[ActuatorSpace]) -> ActuatorSpace:
        """The batches ``parts`` (one robot) as one, in order."""
        arrays: dict[str, Any] = {name: join([getattr(p, name) for p in parts]) for name in ARRAYS}
        kinematics = Kinematics.joined([p.kinematics for p in parts])
        joined = remade(parts[0], kinematics=kinematics, **arrays)
        for name in KEPT.intersection(*(vars(p) for p in parts)):
            vars(joined)[name] = np.concatenate([vars(p)[name] for p in parts])
        return joined


ARRAYS = ("q", "v", "x", "A", "y", "J", "x_ddot")  # the batch's own arrays, batch axis first
KEPT = {"J_H", "_bad", "M", "M_H"}  # derived from q alone: unchanged by v or ẍ


def regularised(space: ActuatorSpace) -> tuple[ActuatorSpace, np.ndarray]:
    """``space`` with A replaced by I where it is singular or the state is not finite, so that
    every derived quantity is defined on the whole batch, and where that was, (k,) bool. What is
    derived there is meaningless: callers freeze or exclude those states."""
    bad = space._bad
    if bad.any():
        eye = np.eye(space.A.shape[-1])
        space = remade(space, A=np.where(bad[:, None, None], eye, space.A))
    return space, bad


def evaluate(robot: Robot, q: np.ndarray, v: np.ndarray | None = None) -> ActuatorSpace:
    """`ActuatorSpace` at checked states q (k, n) and v (k, n) or None: the lean entry every
    computation of the toolkit goes through."""
    return _compiled(robot, q, v, False) or _evaluated(robot, q, v)


def _evaluated(robot: Robot, q: np.ndarray, v: np.ndarray | None) -> ActuatorSpace:
    """`evaluate` through Python: the pass, each group of actuator kinds, the task point."""
    kinematics = robot.kinematics(q, v)
    x, A = robot.actuators.evaluate(kinematics)
    y, J = robot.task_point(kinematics)
    return ActuatorSpace(robot, kinematics, q, v, x, A, y, J)


def _compiled(robot: Robot, q, v, finite: bool) -> ActuatorSpace | None:
    """`evaluate` in one call of the core (`Robot.evaluator`), J_H and the bad states included;
    None where it does not serve: a kind or task of your own, q or v not a float array of
    shape (n,) or (k, n) (and finite, if ``finite``)."""
    evaluator = robot.evaluator()
    found = None if evaluator is None else evaluator.evaluate(q, v, finite)
    return None if found is None else compiled_space(robot, found)


def compiled_space(robot: Robot, found: tuple) -> ActuatorSpace:
    """The `ActuatorSpace` of what the core's evaluator ``found``: (q, v, the pass's arrays,
    x, A, y, J, J_H, the bad states, the first state an actuator could not evaluate or None).
    Such a state is bad, as where A is singular (`check_invertible` raises the actuator's
    error). Both frozen dataclasses are made without their __init__, whose object.__setattr__
    per field would cost a one-state evaluation about as much as the core's call."""
    q, v, positions, jacobians, angular, velocities, rates, x, A, y, J, J_H, bad, refused = found
    kinematics = object.__new__(Kinematics)
    vars(kinematics).update(
        tracking=robot.tracking(),
        q=q,
        positions=positions,
        jacobians=jacobians,
        angular=angular,
        v=v,
        velocities=velocities,
        jacobian_rates=rates,
    )
    space = object.__new__(ActuatorSpace)
    vars(space).update(
        robot=robot, kinematics=kinematics, q=q, v=v, x=x, A=A, y=y, J=J, x_ddot=None
    )
    vars(space).update(J_H=J_H, _bad=bad, _refused=refused)
    return space


def joined_found(parts: list[tuple]) -> tuple:
    """What the core's evaluator found for several batches, as found for one batch of them all,
    in order (`compiled_space`): the arrays joined, and the first refusal, its state counted
    in the joined batch."""
    *arrays, refusals = zip(*parts)
    starts = np.cumsum([0] + [len(part[0]) for part in parts])
    refused = next(
        ((starts[i] + r[0], *r[1:]) for i, r in enumerate(refusals) if r is not None), None
    )
    return (*(join(list(values)) for values in arrays), refused)


def actuator_space(robot: Robot, q, v=None, check: bool = True) -> ActuatorSpace:
    """`ActuatorSpace` at q of shape (n,) or (k, n) and joint velocities v like q (default rest).

    One state comes back as a batch of one. ``check`` raises `SingularConfigurationError` where
    A is singular.
    """
    require_robot(robot)
    space = _compiled(robot, q, v, True)
    if space is None:
        qb = robot.configuration(q)
        vb = None if v is None else robot.configuration(v, "v")
        if vb is not None and vb.shape != qb.shape:
            raise InvalidInputError(f"v has shape {vb.shape}; q has {qb.shape}")
        space = evaluate(robot, qb, vb)
    if check and np.count_nonzero(space._bad):  # the cheapest test of a small batch
        check_invertible(space)
    return space
