"""Instantaneous redundancy resolution laws in actuator coordinates: ẋ = resolve(state, ẏ).

A law is a weight W(state) and an optional null-space term z(state). It answers

    ẋ = J_W⁺ ẏ + (I − J_W⁺ J_H) z,     J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹   (Eqs. 1, 27)

the solution of J_H ẋ = ẏ (Eq. 16) nearest z in the norm ẋᵀ W ẋ: with z = 0, the one of least
ẋᵀ W ẋ. W = I gives the minimum actuator-velocity norm (Eqs. 24, 26), W = M_H the minimum
kinetic energy (Eqs. 29, 32), W = diag(A_A²) the least sum of squared piston-side flows
(`MinFlow`); gradient projection is W = I with z = α ∇Φ (Eq. 1).

The kernel never inverts W: it takes the least-norm solution d₀ = J_Hᵀ G⁻¹ (ẏ − J_H z), G =
J_H J_Hᵀ, then moves it along the null space N of J_H to the least dᵀ W d (u = −(Nᵀ W N)⁻¹ Nᵀ W
d₀), which is J_W⁺ (ẏ − J_H z) wherever W is invertible, and stays exact where W is near
singular but positive on the self-motions (a link of almost no mass makes M_H so). Near a
singularity of J_H (the task Jacobian losing rank) the m×m matrix G is damped: λ² I is added
to it, λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), when the ratio of its smallest to its largest
eigenvalue falls below ε (Nakamura and Hanafusa's variable damping, made scale-free). ẋ then
stays finite and bounded, and J_H ẋ departs from ẏ by an amount the integrators report as
tracking error; away from singularities the laws are exact.

`Resolver.resolve` serves a batch of states, `Resolver.step` one configuration in a control
loop; both run the same compiled kernel (`redundancy._core.resolve`), to which a law passes its
W and z.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from redundancy import _core
from redundancy.errors import InvalidInputError
from redundancy.model.actuators import declared
from redundancy.model.robot import Robot, require_robot
from redundancy.model.schema import excerpt
from redundancy.model.values import is_real
from redundancy.resolution.state import (
    SINGULAR_TOLERANCE,
    ActuatorSpace,
    actuator_space,
    check_invertible,
    evaluate,
    per_state,
)

# The gradient-projection gain α, m²/s, tuned on the paper's segments by
# `tune_gradient_projection` of benchmarks/peers.py: the least worst-case peak ẋᵀẋ among the
# gains that keep every stroke inside its limits from the default starts (see
# benchmarks/results.md).
TUNED_GAIN = 0.07
MAX_GAIN = 1e3  # m²/s: a pull of 10³ m/s at 1 m from mid-stroke, beyond any actuator's speed
SINGULAR_RATIO = 1e-8  # ε: G counts as near singular below σ_min / σ_max = ε (cond J_H ≈ 1e4)


class Step(NamedTuple):
    """One control step at one configuration: ẋ (n,) m/s, q̇ = A⁻¹ ẋ (n,), and the task point
    y (m,) m the step started from (for a closed-loop term)."""

    x_dot: np.ndarray
    q_dot: np.ndarray
    y: np.ndarray


class State(NamedTuple):
    """The robot in actuator coordinates at one configuration, as a control loop reads it:
    strokes x (n,), A = ∂x/∂q (n, n) (Eq. 10), J_H = J A⁻¹ (m, n) (Eq. 16) and
    M_H = A⁻ᵀ M A⁻¹ (n, n) (Eq. 22), the mass each actuator moves (kg; kg·m² where an actuator
    turns), None on a robot without masses."""

    x: np.ndarray
    A: np.ndarray
    J_H: np.ndarray
    M_H: np.ndarray | None


def _task_velocities(space: ActuatorSpace, y_dot) -> np.ndarray:
    """ẏ (k, m) for the k states of ``space``, checked (`per_state`)."""
    return per_state(y_dot, "y_dot", np.shape(space.J)[:2])


class Resolver:
    """A resolution law: its weight W (`weight`) and null-space term z (`null_space`).

    A law of your own is a subclass overriding either; the base is the unweighted
    pseudoinverse with no null-space term.
    """

    name: str = "unweighted pseudoinverse (min ẋᵀẋ)"

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def weight(self, space: ActuatorSpace) -> np.ndarray | None:
        """W (k, n, n), symmetric positive definite, or None for W = I."""
        return None

    def null_space(self, space: ActuatorSpace) -> np.ndarray | None:
        """z (k, n) in m/s, projected onto the null space of J_H, or None for z = 0."""
        return None

    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        """ẋ (k, n) for task velocities ẏ (k, m) at the states of ``space``:
        ẋ = J_W⁺ (ẏ − J_H z) + z, the module docstring's law."""
        y_dot = _task_velocities(space, y_dot)
        W, z = self.weight(space), self.null_space(space)
        return _core.resolve(space.J_H, y_dot, W, z, SINGULAR_RATIO)

    def resolve_at(self, space: ActuatorSpace, y_dot: np.ndarray, t: np.ndarray) -> np.ndarray:
        """`resolve` at times t (k,) in s along a segment: the integrators call this, so that a
        law may follow a plan in time (`redundancy.planning.cycles.HeldReference`); the laws
        here do not depend on time."""
        return self.resolve(space, y_dot)

    def step(self, robot: Robot, q: np.ndarray, y_dot: np.ndarray) -> Step:
        """The law at one configuration q (n,) for the task velocity ẏ (m,) m/s: one control
        step, by the same code as `resolve` on a batch of one. Both are checked (shape, finite:
        `InvalidInputError`), and so is A (`SingularConfigurationError` where it is singular,
        as `actuator_space` raises); a step that overflows to inf or NaN is refused
        (`InvalidInputError`)."""
        states, velocities = robot.configuration(q), robot.task_values(y_dot)
        if len(states) != 1 or len(velocities) != 1:
            raise InvalidInputError(
                f"a step takes one q ({robot.n},) and one y_dot ({robot.m},); got "
                f"{np.shape(q)} and {np.shape(y_dot)}"
            )
        space = evaluate(robot, states)
        check_invertible(space)
        x_dot = self.resolve(space, velocities)
        finite = np.isfinite(x_dot).all()  # else q̇ is not solved for: the law's ẋ is named
        q_dot = space.joint_velocities(x_dot) if finite else x_dot
        if not (finite and np.isfinite(q_dot).all()):
            raise InvalidInputError(
                f"{self.name}: the step at q = {robot.written(states[0])} for ẏ = "
                f"{robot.written(velocities[0])} is not finite: the law's numbers overflow or "
                f"divide by zero there (the joints' limits: {robot.written(robot.lower)} to "
                f"{robot.written(robot.upper)})"
            )
        return Step(x_dot[0], q_dot[0], space.y[0])


def require_resolver(resolver: object) -> Resolver:
    """``resolver`` if it is a `Resolver`; else one line saying what a law is."""
    if not isinstance(resolver, Resolver):
        raise InvalidInputError(
            f"a law must be a Resolver (an objective's .resolver, MinVelocityNorm(), a subclass "
            f"of your own); got {excerpt(resolver)}"
        )
    return resolver


class MinVelocityNorm(Resolver):
    """ẋ = J_H⁺ ẏ (Eq. 24): among all ẋ with J_H ẋ = ẏ, the one of least ẋᵀẋ."""


class MinKineticEnergy(Resolver):
    """ẋ = J_MH⁺ ẏ (Eqs. 29, 32): among all ẋ with J_H ẋ = ẏ, the one of least ẋᵀ M_H ẋ."""

    name = "M_H-weighted pseudoinverse (min ẋᵀ M_H ẋ)"

    def weight(self, space: ActuatorSpace) -> np.ndarray:
        return space.M_H


class MinFlow(Resolver):
    """ẋ = J_W⁺ ẏ with W = diag(A_A²): among all ẋ with J_H ẋ = ẏ, the one of least Σ (A_A,i ẋ_i)²,
    the squared piston-side flows of the robot's cylinders (`redundancy.model.hydraulics`).
    W is scaled to a mean of 1 over the cylinders; actuators that are not cylinders weigh as the
    mean cylinder. A robot without hydraulics raises `InvalidInputError`."""

    name = "flow-weighted pseudoinverse (min Σ (A_A ẋ)²)"

    def weight(self, space: ActuatorSpace) -> np.ndarray:
        return np.broadcast_to(self.constant_weight(space.robot), space.A.shape)

    @staticmethod
    def constant_weight(robot: Robot) -> np.ndarray:
        """W (n, n), the same at every state of ``robot``."""
        circuit = robot.circuit()
        diagonal = np.ones(robot.n)
        diagonal[circuit.columns] = circuit.piston_areas**2 / np.mean(circuit.piston_areas**2)
        return np.diag(diagonal)


class GradientProjection(Resolver):
    """ẋ = J_H⁺ ẏ + (I − J_H⁺ J_H) z, z = α ∇Φ(x) (Eq. 1 in actuator coordinates).

    Φ(x) = −½ Σ_i ((x_i − x̄_i) / (x_i,max − x_i,min))² rewards strokes near mid-range x̄
    (Liégeois' joint-limit avoidance, on actuators), so z_i = −α (x_i − x̄_i) / Δx_i², in m/s for
    the gain α in m²/s. Actuators with infinite strokes are not pushed. The null-space term
    leaves J_H ẋ = ẏ unchanged. This is the baseline the paper argues against.
    """

    name = "gradient projection (limit avoidance)"

    def __init__(self, gain: float = TUNED_GAIN):
        if not (is_real(gain) and 0 <= gain <= MAX_GAIN):
            raise InvalidInputError(
                f"GradientProjection: gain must be a number within [0, {MAX_GAIN:g}] m²/s "
                f"(tuned: {TUNED_GAIN}); got {gain!r}"
            )
        self.gain = float(gain)

    def __repr__(self) -> str:
        return f"GradientProjection(gain={self.gain})"

    def null_space(self, space: ActuatorSpace) -> np.ndarray:
        pull, middle = self.pull(space.robot)
        return pull * (space.x - middle)

    def pull(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """z = pull ∘ (x − x̄): pull = −α / Δx² (n,) (0 for an infinite stroke) and x̄ (n,)."""
        actuators = robot.actuators
        span = actuators.upper - actuators.lower
        finite = np.isfinite(span)
        middle = (
            np.where(finite, actuators.upper, 0.0) + np.where(finite, actuators.lower, 0.0)
        ) / 2
        scale = np.where(finite, 1 / np.where(finite, span, 1.0) ** 2, 0.0)
        return -self.gain * scale, middle


class HeldRates(Resolver):
    """A law that moves the held actuators ``rows`` (n − m of them) at rates of its own,
    ẋ_h = `held_velocity`(t, x_h), and the others so as to resolve the task, J_H ẋ = ẏ: the one
    ẋ solving [J_H; E_h] ẋ = [ẏ; ẋ_h] (n equations; E_h the rows of I that pick the held
    actuators), by the compiled core (`_core.held`), in the integrators' loop too. It depends on
    time, so it answers `resolve_at` only. A subclass gives `held_velocity`
    (`redundancy.planning.cycles.HeldReference`: a periodic plan's r(t) followed with feedback).
    """

    def __init__(self, rows: int | Sequence[int]):
        self.rows = [int(rows)] if isinstance(rows, int | np.integer) else list(rows)

    def held_velocity(self, t: np.ndarray, x_h: np.ndarray) -> np.ndarray:
        """ẋ_h (k, h) at times t (k,) s where the held actuators' strokes are x_h (k, h)."""
        raise NotImplementedError

    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        raise InvalidInputError("this law follows a plan in time; call resolve_at(space, ẏ, t)")

    def resolve_at(self, space: ActuatorSpace, y_dot: np.ndarray, t: np.ndarray) -> np.ndarray:
        t = np.broadcast_to(np.asarray(t, dtype=float), (len(space.x),))
        rates = self.held_velocity(t, space.x[:, self.rows])
        return _core.held(space.J_H, _task_velocities(space, y_dot), self.rows, rates)


class Controller:
    """A law bound to a robot for a control loop: ``Controller(robot, law).step(q, y_dot)``.

    The robot, the law and what the law reads of the robot (W for `MinFlow`, the strokes for
    `GradientProjection`, the masses for `MinKineticEnergy`) are checked once, here. Where the
    robot's actuators are built-in kinds and the law is one of this module's, each step is one
    call of the compiled core (`redundancy._core.Controller`): the pass at q, y and J, x and A,
    J_H = J A⁻¹, W and z, the kernel, q̇ = A⁻¹ ẋ. It checks only that q (n,) and ẏ (m,) are
    finite float arrays, that A is not singular and that ẋ and q̇ came out finite; anything
    else (a list, a NaN, a singular A, a step that overflows) is answered by `Resolver.step`,
    which raises the toolkit's one-line errors. A kind or a
    law of your own (any of ``weight``, ``null_space``, ``resolve``, ``step`` overridden), or a
    task other than the tool's position, runs `Resolver.step` on every call, as the same object.
    `state` is the state a step reads, with M_H (say, to schedule a servo's gains on the mass
    each cylinder moves), in one call by the same evaluation, answered likewise by
    `actuator_space` where the core does not serve it. A state does not depend on the law: with
    a law of your own it is read compiled all the same, where the robot's kinds and task are
    built in.

    The controller reads the robot as it was when built: build another after changing it.
    """

    def __init__(self, robot: Robot, law: Resolver):
        require_robot(robot)
        if not isinstance(law, Resolver):
            raise InvalidInputError(
                f"a controller takes a law, a Resolver (e.g. VELOCITY.resolver); got {law!r}"
            )
        self.robot, self.law = robot, law
        self._python = functools.partial(law.step, robot)
        # the core keeps both fallbacks: neither may hold this object, a cycle through the
        # compiled object that the garbage collector cannot see
        self._python_state = functools.partial(python_state, robot)
        self._compiled = compiled(robot, law, self._python, self._python_state)
        # a state does not depend on the law: with a law of your own, the plainest built-in
        # one's compiled object reads it
        self._states = self._compiled or compiled(
            robot, MinVelocityNorm(), self._python, self._python_state
        )

    def __repr__(self) -> str:
        return f"Controller({self.robot!r}, {self.law!r})"

    def __reduce__(self):
        """Pickled as its robot and law, and built again (its compiled object is not data)."""
        return Controller, (self.robot, self.law)

    @property
    def is_compiled(self) -> bool:
        """Whether each step is one call of the compiled core."""
        return self._compiled is not None

    def step(self, q: np.ndarray, y_dot: np.ndarray) -> Step:
        """One control step at q (n,) for the task velocity ẏ (m,) m/s: what `Resolver.step`
        gives, to rounding."""
        if self._compiled is None:
            return self._python(q, y_dot)
        return self._compiled.step(q, y_dot)

    def state(self, q: np.ndarray) -> State:
        """The robot at q (n,) in actuator coordinates: what `actuator_space` gives of x, A,
        J_H and M_H there, to rounding; `InvalidInputError` and `SingularConfigurationError`
        as it raises them."""
        if self._states is None:
            return self._python_state(q)
        return self._states.state(q)


def python_state(robot: Robot, q) -> State:
    """`Controller.state` through `actuator_space`, with its checks and errors."""
    states = robot.configuration(q)
    if len(states) != 1:
        raise InvalidInputError(f"a state takes one q ({robot.n},); got shape {np.shape(q)}")
    space = actuator_space(robot, states)
    M_H = None if robot.kinematic_only else space.M_H[0]
    return State(space.x[0], space.A[0], space.J_H[0], M_H)


def compiled(robot: Robot, law: Resolver, fallback, state_fallback) -> _core.Controller | None:
    """The compiled step of ``law`` on ``robot``, or None where the core cannot run it alone
    (`Controller`); ``fallback`` and ``state_fallback`` are the Python step and state it calls
    for what it refuses."""
    found = rule(robot, law, ("resolve", "step"))
    if found is None:
        return None
    tracking = robot.tracking()
    tool, rows = robot.task_rows
    return _core.Controller(
        tracking.core,
        tracking.slots[tool],
        rows,
        *declared(list(robot.actuators), tracking.slots),
        *found,
        SINGULAR_RATIO,
        SINGULAR_TOLERANCE,
        fallback,
        Step,
        state_fallback,
        State,
        not robot.kinematic_only,
    )


def compiled_rates(robot: Robot, law: Resolver) -> _core.Rates | None:
    """The compiled right-hand side q̇ = A⁻¹ ẋ of ``law`` on ``robot`` for the integrator
    (`redundancy.planning.integrate`), or None where the core cannot run it alone: a kind, a
    task or a law of your own (``resolve_at`` overridden too). A `HeldRates` law runs in the
    core with its ``held_velocity`` called once per batch."""
    if isinstance(law, HeldRates):
        evaluator = robot.evaluator()
        if evaluator is None or type(law).resolve_at is not HeldRates.resolve_at:
            return None
        return _core.Rates(evaluator, law.rows, law.held_velocity)
    found = rule(robot, law, ("resolve", "resolve_at"))
    return None if found is None else _core.Rates(robot.evaluator(), *found, SINGULAR_RATIO)


def rule(robot: Robot, law: Resolver, methods: tuple[str, ...]) -> tuple | None:
    """The core's form of ``law`` on ``robot``: its weight (I, M_H or a constant W), W, and the
    null-space pull and middle (`GradientProjection.pull`) or None, None; None where the law
    overrides any of ``methods`` or its weight or null-space term is of its own, or where the
    robot has a kind or a task of its own (`Robot.evaluator`)."""
    kind = type(law)
    weights = {
        Resolver.weight: IDENTITY,
        MinKineticEnergy.weight: INERTIA,
        MinFlow.weight: CONSTANT,
    }
    own = any(getattr(kind, name) is not getattr(Resolver, name) for name in methods)
    pulls = kind.null_space is GradientProjection.null_space
    if (
        own
        or kind.weight not in weights
        or not (pulls or kind.null_space is Resolver.null_space)
        or robot.evaluator() is None
    ):
        return None
    weight = weights[kind.weight]
    if weight == INERTIA:
        robot.require_masses("M(q) and the dynamics (M_H, the energy law)")
    W = law.constant_weight(robot) if weight == CONSTANT else None  # type: ignore[attr-defined]
    pull, middle = law.pull(robot) if pulls else (None, None)  # type: ignore[attr-defined]
    return weight, W, pull, middle


IDENTITY, INERTIA, CONSTANT = 0, 1, 2  # the core's weights: I, M_H, a constant W
