"""A faster improved initial configuration, and the resolver laws evaluated lean.

The paper's search (section 2, steps i-v; `redundancy.initial_configuration.improved_start`)
sweeps the held actuator uniformly and integrates every sample on a fine fixed grid. For one
held actuator (r = n − m = 1), `fast_start` finds the same best start from a few dozen
integrations by using the structure of the problem:

- The feasible set. The margin μ(v) of a start v is the least distance of a checked actuator to
  its stroke limits over the whole motion, and of the start configuration to its joint limits
  (m or rad; negative once a limit is passed). It is continuous in v, so the ends of the
  feasible set are its zeros. The joint-limit part needs no integration: the ends of the
  reachable starts are located first, by Newton continuation of the start configuration along
  v alone. A grid over the reachable starts then brackets the zeros of μ, and each round probes
  every bracket at the zeros of the line through its ends, of the lines through the two nearest
  values on either side (μ may have a kink at its zero, where the binding limit changes, and
  then a side's own line is the accurate one) and of the parabolas through three neighbours,
  0.45 of a tolerance either side of each (a zero that close closes the bracket), and at the
  bracket's midpoint where those zeros disagree, until every end is located to ``tolerance``.
- The peak along the range. The best start is the feasible start of least peak among the grid,
  the located ends and, where the least peak lies between two feasible starts of higher peak,
  the vertices of parabolas through the three. On the crane the peak falls towards the upper end
  of every feasible range, so the best start is a located end.
- Adaptive integration. Dormand-Prince 5(4) steps with error control on q, each start with its
  own step size, integrate the law q̇ = A⁻¹ ẋ, ẋ = resolver(ẏ_d), instead of RK4 at 0.01 s
  with a closed-loop term; the motions are sampled at the accepted steps and their midpoints,
  and the strokes between samples follow the cubic Hermite interpolant through x and ẋ, so a
  limit passed between samples still counts. Strokes along an integrated motion count
  `ALLOWANCE` × the tolerance closer to their limits (the start itself is exact), so that a
  start found feasible is feasible under `simulate` too. On the grid, a motion that is past a
  limit, with both its neighbours, is stopped: it cannot end a bracket.
- Vectorised batches. All starts of a round are one state vector of the integrator, evaluated by
  `FastResolver.rates`.

`FastResolver` evaluates the pseudoinverse laws (Eqs. 24, 32) straight from Pinocchio's frame
Jacobians, in joint coordinates: for a batch (`rates`, used by the integrator) and for one state
in a control loop (`step`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv, dpotrf, dpotrs

from redundancy.actuator_space import singular as singular_states
from redundancy.actuators import Identity, LinearCylinder
from redundancy.errors import InvalidInputError, SingularConfigurationError, UnreachableError
from redundancy.ik import DAMPING, TOLERANCE, held_indices, inverse_kinematics
from redundancy.initial_configuration import Sample, SampledStarts, sweep_values
from redundancy.objectives import VELOCITY, Objective
from redundancy.resolvers import (
    SINGULAR_RATIO,
    MinKineticEnergy,
    MinVelocityNorm,
    weighted_pseudoinverse,
)
from redundancy.robot import AXES, Robot
from redundancy.simulate import LIMIT_TOLERANCE, TIME_STEP, Trajectory, simulate
from redundancy.tasks import Segment

GRID = 12  # integrated starts of the first round, evenly over the reachable ones
REACH_GRID = 24  # starts whose reachability is checked first, evenly over the held stroke
END_TOLERANCE = 5e-4  # of the held stroke: the ends of the feasible set are located to this,
# half the spacing of a 1,000-sample sweep
ROUNDS = 8  # refinement rounds, at most, of each phase
INTEGRATION_TOLERANCE = 1e-6  # relative and absolute error per step on q (rad, m)
ALLOWANCE = 30  # strokes along an integrated motion count ALLOWANCE × tolerance (m) closer to
# their limits: the integrator's error in x, measured below 6 × tolerance on the crane
NEWTON_ITERATIONS = 10  # from a configuration nearby, Newton converges in about 4
FOUND = 1e3 * TOLERANCE  # m: a Newton residual below this has found a configuration
WORLD = pin.LOCAL_WORLD_ALIGNED


class State(NamedTuple):
    """Kinematics at k states: strokes x (k, n) m, A = ∂x/∂q (k, n, n), task point y (k, m) m,
    task Jacobian J (k, m, n)."""

    x: np.ndarray
    A: np.ndarray
    y: np.ndarray
    J: np.ndarray


class Rates(NamedTuple):
    """The law at k states: ẋ (k, n) m/s, q̇ (k, n), the objective's measure (k,) (ẋᵀẋ in
    m²/s² or ẋᵀ M_H ẋ in J), whether A is singular there (k,), and the kinematics."""

    x_dot: np.ndarray
    q_dot: np.ndarray
    measure: np.ndarray
    singular: np.ndarray
    state: State


class Step(NamedTuple):
    """One control step at one state: ẋ (n,) m/s, q̇ = A⁻¹ ẋ (n,), and the task point y (m,) m
    the step started from (for the closed-loop term)."""

    x_dot: np.ndarray
    q_dot: np.ndarray
    y: np.ndarray


def _index(rows: np.ndarray) -> slice | np.ndarray:
    """``rows`` as a slice where they are evenly spaced and increasing: a view, cheaper to take
    than a fancy index."""
    steps = set(np.diff(rows).tolist())
    if len(rows) == 1 or (len(steps) == 1 and min(steps) > 0):
        return slice(int(rows[0]), int(rows[-1]) + 1, int(max(steps, default=1)))
    return rows


class FastResolver:
    """The objective's pseudoinverse law (Eq. 24 or 32), lean, in joint coordinates:

        q̇ = W⁻¹ Jᵀ (J W⁻¹ Jᵀ + λ² I)⁻¹ ẏ,   ẋ = A q̇,   measure = q̇ᵀ W q̇,

    with W = AᵀA for min ẋᵀẋ (ẋᵀẋ = q̇ᵀ AᵀA q̇) and W = M for min ẋᵀ M_H ẋ (= q̇ᵀ M q̇). This is
    the ẋ of `MinVelocityNorm` and `MinKineticEnergy`: J W⁻¹ Jᵀ equals their J_H W_H⁻¹ J_Hᵀ, so
    the damping λ² near a singularity is theirs too (`weighted_pseudoinverse`).

    x, A and J come from Pinocchio's frame Jacobians of the tool and the cylinder attachments
    (one Jacobian pass per state); actuators must be `LinearCylinder`, `Prismatic` or
    `Identity`. `rates` serves a batch, `step` one state with LAPACK's small solves. Both skip
    the damping where det G / (tr G)^m, a lower bound on σ_min / σ_max of G = J W⁻¹ Jᵀ, is at
    least `SINGULAR_RATIO`, which proves λ² = 0.
    """

    def __init__(self, robot: Robot, objective: Objective = VELOCITY):
        resolver = objective.resolver
        if type(resolver) not in (MinVelocityNorm, MinKineticEnergy):
            raise InvalidInputError(
                f"FastResolver runs the pseudoinverse laws MinVelocityNorm and "
                f"MinKineticEnergy; objective {objective.name!r} uses {resolver!r}"
            )
        other = [a.name for a in robot.actuators if not isinstance(a, LinearCylinder | Identity)]
        if other:
            raise InvalidInputError(
                f"FastResolver evaluates LinearCylinder, Prismatic and Identity actuators; "
                f"{other} are of other kinds: use the resolvers on `actuator_space`"
            )
        self.robot = robot
        self.objective = objective
        self.energy = isinstance(resolver, MinKineticEnergy)
        names = robot.actuators.names
        cylinders = [a for a in robot.actuators if isinstance(a, LinearCylinder)]
        direct = [a for a in robot.actuators if not isinstance(a, LinearCylinder)]
        self._cylinders = _index(np.array([names.index(a.name) for a in cylinders], dtype=int))
        self._direct_rows = np.array([names.index(a.name) for a in direct], dtype=int)
        self._direct_joints = np.array([a.index for a in direct], dtype=int)
        self._offsets = np.array([a.offset for a in direct])  # type: ignore[attr-defined]
        tool = robot.model.getFrameId(robot.tool_frame)
        self._frames = [tool] + [f for a in cylinders for f in a.frames]  # tool, base, rod, ...
        self._task = _index(np.array([AXES.index(a) for a in robot.task_axes]))
        self._A = np.zeros((robot.n, robot.n))
        self._A[self._direct_rows, self._direct_joints] = 1.0

    def state(self, q: np.ndarray) -> State:
        """x, A (Eqs. 9, 11, 14), y and J (Eqs. 6-7) at the configurations q (k, n)."""
        model, data, frames = self.robot.model, self.robot.data, self._frames
        gathered, placed = [], []
        for qi in q:
            pin.computeJointJacobians(model, data, qi)
            for frame in frames:
                gathered.append(pin.getFrameJacobian(model, data, frame, WORLD))
                # updateFramePlacement hands back data.oMf[frame], faster than indexing it
                placed.append(pin.updateFramePlacement(model, data, frame).translation.copy())
        jacobians = np.array(gathered).reshape(len(q), len(frames), 6, model.nv)[:, :, :3]
        points = np.array(placed).reshape(len(q), len(frames), 3)
        d = points[:, 2::2] - points[:, 1::2]  # rod − base, per cylinder
        length = np.sqrt(np.einsum("kci,kci->kc", d, d))
        relative = jacobians[:, 2::2] - jacobians[:, 1::2]
        A = np.repeat(self._A[None], len(q), axis=0)
        A[:, self._cylinders] = ((d / length[..., None])[:, :, None] @ relative)[:, :, 0]
        x = np.empty_like(q)
        x[:, self._cylinders] = length
        x[:, self._direct_rows] = q[:, self._direct_joints] + self._offsets
        return State(x, A, points[:, 0, self._task], jacobians[:, 0, self._task])

    def rates(self, q: np.ndarray, y_dot: np.ndarray) -> Rates:
        """The law at states q (k, n) for task velocities ẏ (k, m); states where A is singular
        get ẋ = q̇ = 0."""
        state = self.state(q)
        A, J = state.A, state.J
        singular = singular_states(A)
        if singular.any():
            A = np.where(singular[:, None, None], np.eye(len(A[0])), A)
        W = self.robot.mass(q) if self.energy else np.swapaxes(A, 1, 2) @ A
        W_inv_J_T = np.linalg.solve(W, np.swapaxes(J, 1, 2))
        G = J @ W_inv_J_T
        if np.all(np.linalg.det(G) >= SINGULAR_RATIO * np.einsum("kii->k", G) ** len(G[0])):
            q_dot = (W_inv_J_T @ np.linalg.solve(G, y_dot[..., None]))[..., 0]
        else:
            q_dot = (weighted_pseudoinverse(J, W_inv_J_T) @ y_dot[..., None])[..., 0]
        q_dot[singular] = 0.0
        measure = np.einsum("ki,kij,kj->k", q_dot, W, q_dot)
        return Rates((A @ q_dot[..., None])[..., 0], q_dot, measure, singular, state)

    def step(self, q: np.ndarray, y_dot: np.ndarray) -> Step:
        """The law at one configuration q (n,) for the task velocity ẏ (m,) m/s."""
        model, data, frames, world = self.robot.model, self.robot.data, self._frames, WORLD
        pin.computeJointJacobians(model, data, q)
        jacobians = np.array([pin.getFrameJacobian(model, data, f, world) for f in frames])
        points = np.array([pin.updateFramePlacement(model, data, f).translation for f in frames])
        d = points[2::2] - points[1::2]
        lengths = np.array([math.hypot(*vector) for vector in d.tolist()]).reshape(-1, 1)
        relative = jacobians[2::2, :3] - jacobians[1::2, :3]
        A = self._A.copy()
        A[self._cylinders] = (d[:, None] @ relative)[:, 0] / lengths
        J = jacobians[0, self._task]
        W = pin.crba(model, data, q) if self.energy else A.T @ A  # crba fills the upper triangle
        _, W_inv_J_T, info = dposv(W, J.T, lower=0)
        if info:
            raise SingularConfigurationError(
                f"actuator Jacobian A is singular at q = {np.round(q, 6).tolist()}"
            )
        G = J @ W_inv_J_T
        factor, info = dpotrf(G)
        determinant = math.prod(factor.diagonal().tolist()) ** 2
        if info == 0 and determinant >= SINGULAR_RATIO * sum(G.diagonal().tolist()) ** len(G):
            q_dot = W_inv_J_T @ dpotrs(factor, y_dot)[0]
        else:
            q_dot = weighted_pseudoinverse(J[None], W_inv_J_T[None])[0] @ y_dot
        return Step(A @ q_dot, q_dot, points[0, self._task])


# Dormand-Prince 5(4): stage weights (the last row gives the 5th-order step, whose rates are
# the next step's first stage), the error weights (5th − 4th order), and the 4th-order dense
# output at the middle of a step (Shampine's).
DORMAND_PRINCE = (
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
ERROR_WEIGHTS = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)
MIDPOINT_WEIGHTS = (
    6025192743 / 60171106304,
    0.0,
    51252292925 / 130801643196,
    -2691868925 / 90256659456,
    187940372067 / 3189068634112,
    -1776094331 / 39487288512,
    11237099 / 470086768,
)


class Motions(NamedTuple):
    """k motions, each sampled at its own times and padded to T samples by repeating its last:
    t (k, T) s; q, x, x_dot (k, T, n); y (k, T, m) m; the law's measure (k, T); failed (k,)
    where A turned singular, stopped (k,) where `integrate` stopped a motion past its strokes
    (both end there)."""

    t: np.ndarray
    q: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    y: np.ndarray
    measure: np.ndarray
    failed: np.ndarray
    stopped: np.ndarray


def _combine(weights, stages):
    return sum(w * stage for w, stage in zip(weights, stages) if w)


def integrate(
    law: FastResolver,
    segment: Segment,
    starts: np.ndarray,
    tolerance: float = INTEGRATION_TOLERANCE,
    strokes: tuple[np.ndarray, np.ndarray] | None = None,
) -> Motions:
    """The law's motions along ``segment`` from every start (k, n), by Dormand-Prince 5(4)
    steps with error control ``tolerance`` (relative and absolute, on q) for each start.

    The law is autonomous (ẏ_d is constant and there is no closed-loop term, so the tracking
    error is the integration error): every start keeps its own time and step size, and each
    stage is one batched evaluation of the starts still running. A motion is sampled at its
    accepted steps and at their midpoints (the method's dense output). With ``strokes``
    (lower (n,), upper (n,)), a motion stops (`Motions.stopped`) once it and the motions before
    and after it in the batch have all passed them at a step.
    """
    robot = law.robot
    starts = robot.configuration(starts, "starts")
    k, duration, velocity = len(starts), segment.duration, segment.velocity

    def rates(q: np.ndarray) -> Rates:
        return law.rates(q, np.broadcast_to(velocity, (len(q), robot.m)))

    first = rates(starts)
    nodes, middles = [(np.arange(k), np.zeros(k), starts, first)], []
    t, q, f, failed = np.zeros(k), starts.copy(), first.q_dot, first.singular.copy()
    past, stopped = np.zeros(k, dtype=bool), np.zeros(k, dtype=bool)
    scale = tolerance * (1 + np.abs(q))
    size = np.sqrt(np.mean((q / scale) ** 2, axis=1))
    speed = np.sqrt(np.mean((f / scale) ** 2, axis=1))
    h = np.minimum(duration, 0.01 * size / np.maximum(speed, 1e-12))
    while True:
        rows = np.flatnonzero(~failed & ~stopped & (t < duration))
        if not rows.size:
            break
        step = np.minimum(h[rows], duration - t[rows])[:, None]
        stages = [f[rows]]
        for weights in DORMAND_PRINCE:
            end = rates(q[rows] + step * _combine(weights, stages))
            stages.append(end.q_dot)
            failed[rows[end.singular]] = True
        q_new = q[rows] + step * _combine(DORMAND_PRINCE[-1], stages)
        scale = tolerance * (1 + np.maximum(np.abs(q[rows]), np.abs(q_new)))
        error = np.sqrt(np.mean((step * _combine(ERROR_WEIGHTS, stages) / scale) ** 2, axis=1))
        accept = (error <= 1) & ~failed[rows]
        done = rows[accept]
        nodes.append((done, t[done] + step[accept, 0], q_new[accept], _rows(end, accept)))
        middle = q[done] + step[accept] * _combine(MIDPOINT_WEIGHTS, [s[accept] for s in stages])
        middles.append((done, t[done] + step[accept, 0] / 2, middle))
        t[done] += step[accept, 0]
        q[done], f[done] = q_new[accept], stages[-1][accept]
        growth = np.clip(0.9 * np.maximum(error, 1e-10) ** -0.2, 0.2, 10.0)
        h[rows] = step[:, 0] * np.where(accept, growth, np.minimum(growth, 1.0))
        failed[rows[h[rows] < 1e-9 * duration]] = True
        if strokes is not None:
            x = end.state.x[accept]
            past[done] |= np.any((x < strokes[0]) | (x > strokes[1]), axis=1)
            stopped = past & np.append(True, past[:-1]) & np.append(past[1:], True)
    rows, times, q_middle = (np.concatenate(part) for part in zip(*middles))
    nodes.append((rows, times, q_middle, rates(q_middle)))
    return _assemble(k, nodes, failed, stopped)


def _rows(rates: Rates, mask: np.ndarray) -> Rates:
    """The rates of the states ``mask`` selects."""
    state = State(*(part[mask] for part in rates.state))
    return Rates(
        rates.x_dot[mask], rates.q_dot[mask], rates.measure[mask], rates.singular[mask], state
    )


def _assemble(k: int, nodes, failed: np.ndarray, stopped: np.ndarray) -> Motions:
    """Samples (rows, times, q, rates) of k motions, in time order per motion, padded."""
    rows = np.concatenate([part[0] for part in nodes])
    times = np.concatenate([part[1] for part in nodes])
    order = np.lexsort((times, rows))
    counts = np.bincount(rows, minlength=k)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    index = order[first[:, None] + np.minimum(np.arange(counts.max())[None], counts[:, None] - 1)]

    def gathered(parts):
        return np.concatenate(list(parts))[index]

    return Motions(
        times[index],
        gathered(part[2] for part in nodes),
        gathered(part[3].state.x for part in nodes),
        gathered(part[3].x_dot for part in nodes),
        gathered(part[3].state.y for part in nodes),
        gathered(part[3].measure for part in nodes),
        failed,
        stopped,
    )


def stroke_extremes(
    t: np.ndarray, x: np.ndarray, x_dot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Least and greatest stroke of every actuator over each motion after its start (the start
    itself excluded), (k, n) each, in m, for samples at times t (k, T) of x and ẋ (k, T, n).

    Between samples x follows the cubic Hermite interpolant through x and ẋ at both ends; its
    interior extrema are where its derivative, a quadratic, vanishes.
    """
    h = np.diff(t, axis=1)[:, :, None]
    x0, x1, d0, d1 = x[:, :-1], x[:, 1:], h * x_dot[:, :-1], h * x_dot[:, 1:]
    a = 2 * (x0 - x1) + d0 + d1  # p(s) = a s³ + b s² + d0 s + x0, s ∈ [0, 1]
    b = 3 * (x1 - x0) - 2 * d0 - d1
    discriminant = b * b - 3 * a * d0
    root = np.sqrt(np.maximum(discriminant, 0.0))
    lowest, highest = x[:, 1:].min(axis=1), x[:, 1:].max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cubic = np.abs(a) > 1e-12 * (np.abs(b) + np.abs(d0))
        candidates = [
            np.where(cubic, (-b + root) / (3 * a), -d0 / (2 * b)),
            np.where(cubic, (-b - root) / (3 * a), np.nan),
        ]
    for s in candidates:
        inside = (discriminant >= 0) & (s > 0) & (s < 1)
        s = np.where(inside, s, 0.0)
        value = ((a * s + b) * s + d0) * s + x0
        lowest = np.minimum(lowest, np.where(inside, value, np.inf).min(axis=1))
        highest = np.maximum(highest, np.where(inside, value, -np.inf).max(axis=1))
    return lowest, highest


def joint_margin(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Least distance of each configuration (k, n) to its joint limits (k,), negative outside."""
    return np.minimum(q - robot.lower, robot.upper - q).min(axis=1)


def held_configurations(
    law: FastResolver,
    points: np.ndarray,
    rows: list[int],
    values: np.ndarray,
    guess: np.ndarray,
    iterations: int = NEWTON_ITERATIONS,
) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method on [y(q) − y*, x_h(q) − x_h*] = 0 (Eqs. 6, 10) from ``guess`` (k, n).

    ``points`` (k, m) task points, ``rows`` the r held actuators, ``values`` (k, r) their
    strokes. Unlike `inverse_kinematics` the joint limits do not bind, so a start beyond them is
    found there. Returns the configurations (k, n) and the residual norms (k,) in m.
    """
    q = np.array(guess, dtype=float)
    for _ in range(iterations + 1):
        state = law.state(q)
        residual = np.concatenate([state.y - points, state.x[:, rows] - values], axis=1)
        error = np.linalg.norm(residual, axis=1)
        moving = error > TOLERANCE
        if not moving.any():
            break
        jacobian = np.concatenate([state.J, state.A[:, rows]], axis=1)[moving]
        jacobian_t = np.swapaxes(jacobian, 1, 2)
        normal = jacobian_t @ jacobian + DAMPING * np.eye(len(q[0]))
        q[moving] -= np.linalg.solve(normal, jacobian_t @ residual[moving][..., None])[..., 0]
    return q, error


class _Starts(NamedTuple):
    """Start configurations at held values: values (k,), q (k, n) (beyond the joint limits
    where the start is), margins (k,) (μ, or the joint margin before integration; −inf where no
    configuration reaches the start, or where μ is unknown: a failed or stopped motion)."""

    values: np.ndarray
    q: np.ndarray
    margins: np.ndarray

    def continued(self, law: FastResolver, point: np.ndarray, row: int, values: np.ndarray):
        """Starts at ``values`` (k,), Newton-continued from the nearest found value, and again
        from a nearer one whenever a pass finds one; their margins are joint margins."""
        found = np.isfinite(self.margins)
        known, configurations = self.values[found], self.q[found]
        q = np.empty((len(values), law.robot.n))
        residual = np.full(len(values), np.inf)
        tried = np.full(len(values), np.inf)  # distance of the value last continued from
        pending = np.arange(len(values))
        while pending.size:
            distance = np.abs(values[pending, None] - known[None])
            closer = distance.min(axis=1) < tried[pending]
            pending, nearest = pending[closer], np.argmin(distance, axis=1)[closer]
            if not pending.size:
                break
            tried[pending] = np.abs(values[pending] - known[nearest])
            points = np.broadcast_to(point, (pending.size, law.robot.m))
            q[pending], residual[pending] = held_configurations(
                law, points, [row], values[pending, None], configurations[nearest]
            )
            done = residual[pending] < FOUND
            known = np.concatenate([known, values[pending[done]]])
            configurations = np.concatenate([configurations, q[pending[done]]])
            pending = pending[~done]
        margins = np.where(residual < FOUND, joint_margin(law.robot, q), -np.inf)
        return _Starts(values, q, margins)

    def merged(self, other: _Starts) -> tuple[_Starts, np.ndarray]:
        """Both sets in order of value, and the order (indices into self then other)."""
        order = np.argsort(np.concatenate([self.values, other.values]), kind="stable")
        return (
            _Starts(
                np.concatenate([self.values, other.values])[order],
                np.concatenate([self.q, other.q])[order],
                np.concatenate([self.margins, other.margins])[order],
            ),
            order,
        )


def _bracket_probes(values, margins, inside, tolerance) -> list[float]:
    """Probes for every bracket of ``inside`` (k,) wider than ``tolerance`` (see the module
    docstring): the zeros, in the bracket, of the line through its ends, of the parabolas
    through its ends and either next value, and of each side's own line through its two nearest
    values, at 0.45 of a tolerance either side of each; and the bracket's midpoint where those
    zeros disagree by more than a quarter of it."""
    probes: list[float] = []
    usable = np.isfinite(margins)
    for i in np.flatnonzero(inside[:-1] != inside[1:]):
        a, b = values[i], values[i + 1]
        if b - a <= tolerance:
            continue
        fits = [(i, i + 1), (i - 1, i + 1), (i, i + 2)]  # across the bracket
        sides = [j for j in (i - 1, i + 1) if 0 <= j < len(values) - 1]
        fits += [(j, j + 1) for j in sides if inside[j] == inside[j + 1]]  # each side's own
        zeros = []
        for first, last in fits:
            if first < 0 or last >= len(values) or not usable[first : last + 1].all():
                continue
            v, m = values[first : last + 1], margins[first : last + 1]
            roots = np.roots(np.polyfit(v - a, m, len(v) - 1))
            zeros += [a + z.real for z in roots if z.imag == 0 and 0 < z.real < b - a]
        if not zeros or max(zeros) - min(zeros) > (b - a) / 4:
            probes.append((a + b) / 2)
        for zero in _clusters(sorted(zeros), tolerance):
            probes += list(np.clip(zero + tolerance * np.array([-0.45, 0.45]), a, b))
    return probes


def _clusters(values: list[float], tolerance: float) -> list[float]:
    """The means of runs of sorted ``values`` less than ``tolerance`` apart."""
    runs: list[list[float]] = []
    for value in values:
        if runs and value - runs[-1][-1] < tolerance:
            runs[-1].append(value)
        else:
            runs.append([value])
    return [sum(run) / len(run) for run in runs]


def _new(probes: list[float], values: np.ndarray, tolerance: float) -> np.ndarray:
    """The probes, sorted, without those within a tenth of ``tolerance`` of a known value or
    of a smaller probe."""
    kept: list[float] = []
    for probe in sorted(probes):
        if np.abs(values - probe).min() > tolerance / 10 and (
            not kept or probe - kept[-1] > tolerance / 10
        ):
            kept.append(probe)
    return np.array(kept)


def _vertex_probe(values, peaks, tolerance) -> list[float]:
    """The vertex of the parabola through the least finite peak and its two neighbours, when
    both are finite and higher and they span more than twice ``tolerance``."""
    best = int(np.argmin(peaks))
    if not (0 < best < len(values) - 1 and np.all(np.isfinite(peaks[best - 1 : best + 2]))):
        return []
    v, p = values[best - 1 : best + 2], peaks[best - 1 : best + 2]
    near, far = (v[1] - v[0]) * (p[1] - p[2]), (v[1] - v[2]) * (p[1] - p[0])
    if v[2] - v[0] <= 2 * tolerance or near == far:
        return []
    vertex = v[1] - ((v[1] - v[0]) * near - (v[1] - v[2]) * far) / (2 * (near - far))
    return [float(np.clip(vertex, v[0] + tolerance / 2, v[2] - tolerance / 2))]


@dataclass(frozen=True)
class FastSearch(SampledStarts):
    """Every start `fast_start` integrated or found unreachable along one segment, in order of
    the held value.

    ``samples`` as in `SearchResult` (without violation intervals: ``reason`` names the worst
    excess), each end of the feasible set located to the search's tolerance; ``margins``
    (len(samples),) their margins μ; ``reachable`` the least and greatest reachable start
    located (None if none); ``rounds`` the batched integrations it took;
    ``simulations`` the motions integrated.
    """

    robot: Robot = field(repr=False)
    segment: Segment
    objective: Objective
    held: str
    samples: tuple[Sample, ...]
    margins: np.ndarray
    reachable: tuple[float, float]
    rounds: int
    simulations: int
    checked: tuple[str, ...]

    @property
    def values(self) -> np.ndarray:
        """The held values of the samples, (k,)."""
        return np.array([s.value for s in self.samples])

    def motion(self, time_step: float = TIME_STEP) -> Trajectory:
        """The best start's motion by `simulate`, the integrator of the paper's sweep."""
        best = self.best
        if best is None:
            raise InvalidInputError(f"no feasible start on segment {self.segment.name}")
        ik = inverse_kinematics(
            self.robot, self.segment.start, [self.held], np.array([best.values])
        )
        resolver = self.objective.resolver
        return simulate(self.robot, resolver, self.segment, ik.q, time_step, checked=self.checked)


def _evaluate(
    law, segment, checked, starts: _Starts, tolerance, thin: bool = False
) -> tuple[_Starts, list[Sample]]:
    """Integrate the reachable starts as one batch: their margins μ, and every start's sample.

    ``thin``: stop the motions that, with both neighbours, are certainly infeasible (past a
    checked stroke by more than the error allowance): their μ is not needed (−inf), for they
    cannot end a bracket, and the deepest are the costliest to integrate. Only for the grid,
    whose neighbours are the samples' own."""
    robot = law.robot
    margins = starts.margins.copy()
    samples = [Sample((float(v),), None, False, (), _unreachable(m)) for v, m in zip(*starts[::2])]
    rows = np.flatnonzero(margins >= -LIMIT_TOLERANCE)
    if not rows.size:
        return starts, samples
    columns = [robot.actuators.names.index(name) for name in checked]
    lower, upper = robot.actuators.lower[columns], robot.actuators.upper[columns]
    allowance = ALLOWANCE * tolerance
    beyond = np.array([robot.actuators.lower - allowance, robot.actuators.upper + allowance])
    beyond[:, [i for i in range(robot.n) if i not in columns]] = [[-np.inf], [np.inf]]
    motion = integrate(
        law, segment, starts.q[rows], tolerance, (beyond[0], beyond[1]) if thin else None
    )
    extremes = stroke_extremes(motion.t, motion.x, motion.x_dot)
    lowest, highest = (extreme[:, columns] for extreme in extremes)
    start = motion.x[:, 0, columns]
    along = np.maximum(lower - lowest, highest - upper)  # past each limit, m (k, c)
    at_start = np.maximum(lower - start, start - upper)
    stroke = -np.maximum(along.max(axis=1) + allowance, at_start.max(axis=1))
    unknown = motion.failed | motion.stopped
    margins[rows] = np.minimum(margins[rows], np.where(unknown, -np.inf, stroke))
    for j, row in enumerate(rows):
        feasible = bool(margins[row] >= -LIMIT_TOLERANCE)
        excess = np.maximum(along[j], at_start[j])
        worst = int(np.argmax(excess))
        low = max(lower[worst] - lowest[j, worst], lower[worst] - start[j, worst])
        bound = "lower" if low >= excess[worst] else "upper"
        reason = None
        if motion.failed[j]:
            reason = "singular actuator Jacobian"
        elif motion.stopped[j]:
            reason = f"{checked[worst]} past its {bound} limit, as with its neighbours: stopped"
        elif not feasible and excess[worst] > 0:
            reason = f"{checked[worst]} {excess[worst] * 1000:.3g} mm past its {bound} limit"
        elif not feasible:
            reason = f"{checked[worst]} within the integration error of its {bound} limit"
        peak = float(motion.measure[j].max())
        samples[row] = Sample((float(starts.values[row]),), peak, feasible, (), reason)
    return starts._replace(margins=margins), samples


def _unreachable(margin: float) -> str:
    if not np.isfinite(margin):
        return "start unreachable (no configuration reaches it)"
    return f"start unreachable inside the joint limits (outside them by {-margin:.3g})"


def fast_start(
    robot: Robot,
    segment: Segment,
    objective: Objective = VELOCITY,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    grid: int = GRID,
    tolerance: float | None = None,
    integration_tolerance: float = INTEGRATION_TOLERANCE,
) -> FastSearch:
    """The improved initial configuration (the paper's steps i-v) for one held actuator, from a
    grid refined where it matters (see the module docstring).

    The start configurations are Newton-continued from the multi-seed IK (`inverse_kinematics`,
    as in the sweep) of the start nearest mid-stroke. ``grid`` starts over the reachable ones
    are integrated first; each further round integrates, as one batch, the probes of every
    bracket of the feasible set wider than ``tolerance`` (m, or rad for a rotary actuator; by
    default `END_TOLERANCE` of the held stroke) and of the least peak, until none is left or
    `ROUNDS` have run. ``checked`` names the actuators
    whose strokes count (default all).
    """
    row = held_indices(robot, [held])[0]
    if grid < 3:
        raise InvalidInputError(f"grid must hold at least 3 starts; got {grid}")
    scan = sweep_values(robot, held, REACH_GRID)
    tolerance = END_TOLERANCE * (scan[-1] - scan[0]) if tolerance is None else tolerance
    if not tolerance > 0:
        raise InvalidInputError(f"tolerance must be > 0; got {tolerance}")
    checked = tuple(robot.actuators.names if checked is None else checked)
    unknown = sorted(set(checked) - set(robot.actuators.names))
    if unknown:
        raise InvalidInputError(
            f"unknown actuators {unknown}; actuators: {', '.join(robot.actuators.names)}"
        )
    law = FastResolver(robot, objective)
    point = segment.start
    middle = scan[[np.argmin(np.abs(scan - scan.mean()))]]
    anchor = inverse_kinematics(robot, point, [held], middle[:, None])
    found = _Starts(middle, anchor.q, np.zeros(1))
    reach = found.continued(law, point, row, scan)
    for _ in range(ROUNDS):  # the ends of the reachable starts: no integration needed
        inside = reach.margins >= -LIMIT_TOLERANCE
        probes = _new(
            _bracket_probes(reach.values, reach.margins, inside, tolerance), reach.values, tolerance
        )
        if not probes.size:
            break
        reach = reach.merged(reach.continued(law, point, row, probes))[0]
    reachable = reach.values[reach.margins >= -LIMIT_TOLERANCE]
    if not reachable.size:
        raise UnreachableError(
            f"{robot.name} cannot reach the start {point.tolist()} of segment {segment.name} "
            f"inside its joint limits with {held} anywhere in its stroke"
        )
    values = np.linspace(reachable.min(), reachable.max(), grid)

    def run(starts: _Starts, thin: bool = False) -> tuple[_Starts, list[Sample]]:
        return _evaluate(law, segment, checked, starts, integration_tolerance, thin)

    starts, samples = run(reach.continued(law, point, row, values), thin=True)
    rounds, simulations = 1, sum(s.peak is not None for s in samples)
    for _ in range(ROUNDS):
        feasible = np.array([s.feasible for s in samples])
        peaks = np.array([s.peak if s.feasible else np.inf for s in samples])
        candidates = _bracket_probes(starts.values, starts.margins, feasible, tolerance)
        candidates += _vertex_probe(starts.values, peaks, tolerance)
        probes = _new(candidates, starts.values, tolerance)
        if not probes.size:
            break
        new, new_samples = run(starts.continued(law, point, row, probes))
        starts, order = starts.merged(new)
        samples = [(samples + new_samples)[i] for i in order]
        rounds += 1
        simulations += sum(s.peak is not None for s in new_samples)
    return FastSearch(
        robot,
        segment,
        objective,
        held,
        tuple(samples),
        starts.margins,
        (float(reachable.min()), float(reachable.max())),
        rounds,
        simulations,
        checked,
    )
