"""Inverse kinematics: a configuration that puts the tool at a task point with chosen actuators
held at chosen values (the paper's step iv: the initial configuration from x3init).

With r held actuators and m task coordinates, r = n − m makes the system square:

    h1(q) = y*   (Eq. 6, m equations)      x_h(q) = x_h*   (Eq. 10, r equations)

One routine solves it (`newton`): damped Gauss-Newton steps on the residual, for a batch at
once, optionally projected onto the joint limits. `inverse_kinematics` runs it from several
seeds spread over the joint-limit box and keeps, of the solutions inside the limits, the branch
nearest the middle of the joint ranges; `continue_held` runs it from configurations already
found at nearby held values (continuation along the held stroke), where the limits do not bind,
so that a start beyond them is found there.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from redundancy.errors import InvalidInputError, SingularConfigurationError, UnreachableError
from redundancy.model.robot import Robot
from redundancy.model.values import is_whole
from redundancy.planning.angles import task_labels
from redundancy.planning.tasks import Segment
from redundancy.resolution.limits import amount
from redundancy.resolution.state import SINGULAR_TOLERANCE

TOLERANCE = 1e-12  # m (and m or rad for held actuators): a residual this small has converged
FOUND = 1e3 * TOLERANCE  # a residual below this has found a configuration
ITERATIONS = 40  # from a seed far away
CONTINUATION_ITERATIONS = 10  # from a configuration nearby, Newton converges in about 4
DAMPING = 1e-10
MOST_SEEDS = 1000  # starts per point of inverse_kinematics: each is a Newton solve per value


@dataclass(frozen=True)
class InverseKinematics:
    """Solutions for k held values: q (k, n); reached (k,) whether the point was reached inside
    the joint limits; miss (k,) the smallest residual |[y − y*, x_h − x_h*]| found, in m."""

    q: np.ndarray
    reached: np.ndarray
    miss: np.ndarray


def held_indices(robot: Robot, held: str | Sequence[str]) -> list[int]:
    """Rows of the held actuators (one name, or several), checking there are exactly n − m."""
    rows = robot.actuators.rows(held)
    if len(rows) != robot.n - robot.m:
        raise InvalidInputError(
            f"{robot.name} has n − m = {robot.n - robot.m} redundant degrees; hold that many "
            f"actuators (got {held!r}; actuators: {', '.join(robot.actuators.names)})"
        )
    return rows


def held_names(robot: Robot, held: str | Sequence[str]) -> tuple[str, ...]:
    """The held actuators (one name, or several) as a tuple of names, checked as
    `held_indices` checks them."""
    return tuple(robot.actuators.names[row] for row in held_indices(robot, held))


class _Passes:
    """[y(q); x_h(q)] (m + r,) and [J; A_h] (m + r, n) of every configuration one Newton run
    met, from the frames of the task and the held actuators only, each evaluated once: Newton
    sends many targets from the same seeds, and rows the clip drives into a corner of the joint
    box meet there again and again. Configurations are found again by a hash of their bits
    (sorted, for a binary search) and compared in full."""

    def __init__(self, robot: Robot, rows: list[int]):
        self.robot, self.held = robot, robot.actuators.part(rows)
        self.mix = np.random.default_rng(0).integers(1, 2**62, robot.n) | 1  # odd multipliers
        self.codes = np.zeros(0, dtype=np.int64)  # sorted
        self.q = np.zeros((0, robot.n))
        self.values = np.zeros((0, robot.m + len(rows)))
        self.jacobians = np.zeros((0, robot.m + len(rows), robot.n))

    def _found(self, q: np.ndarray, codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where each of q (k, n) is among the known configurations, and whether it is."""
        at = np.minimum(np.searchsorted(self.codes, codes), max(len(self.codes) - 1, 0))
        if not len(self.codes):
            return at, np.zeros(len(q), dtype=bool)
        return at, (self.codes[at] == codes) & np.all(self.q[at] == q, axis=1)

    def _evaluated(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[y(q); x_h(q)] (k, m + r) and [J; A_h] (k, m + r, n) by one pass."""
        kinematics = self.robot.kinematics(q, actuators=self.held)
        x, A = self.held.evaluate(kinematics)
        y, J = self.robot.task_point(kinematics)
        return np.concatenate([y, x], axis=1), np.concatenate([J, A], axis=1)

    def residual(self, q: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[y(q); x_h(q)] − target (k, m + r) and its Jacobian [J; A_h] (k, m + r, n)."""
        q = np.ascontiguousarray(q)
        codes = q.view(np.int64) @ self.mix  # wraps around: a hash
        at, known = self._found(q, codes)
        if not known.all():
            _, first = np.unique(codes[~known], return_index=True)
            fresh = q[~known][first]
            values, jacobians = self._evaluated(fresh)
            codes_now = np.concatenate([self.codes, codes[~known][first]])
            order = np.argsort(codes_now, kind="stable")
            self.codes, self.q = codes_now[order], np.concatenate([self.q, fresh])[order]
            self.values = np.concatenate([self.values, values])[order]
            self.jacobians = np.concatenate([self.jacobians, jacobians])[order]
            at, known = self._found(q, codes)
        if not known.all():  # two configurations of one hash: this batch as it comes
            values, jacobians = self._evaluated(q)
            return values - target, jacobians
        return self.values[at] - target, self.jacobians[at]


def newton(
    robot: Robot,
    guess: np.ndarray,
    rows: list[int],
    target: np.ndarray,
    iterations: int,
    bounded: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Damped Gauss-Newton on [y(q); x_h(q)] = target (k, n) from ``guess`` (k, n): steps
    δ = (KᵀK + δ₀ I)⁻¹ Kᵀ r with K = [J; A_h] (Eqs. 7, 11), each iterate clipped to the joint
    limits when ``bounded`` (a projected Levenberg-Marquardt). A row stops once its residual is
    below `TOLERANCE` or its step no longer moves it. Returns q (k, n) and |r| (k,)."""
    q = np.array(guess, dtype=float)
    passes = _Passes(robot, rows)
    active = np.arange(len(q))
    eye = DAMPING * np.eye(robot.n)
    for _ in range(iterations):
        residual, jacobian = passes.residual(q[active], target[active])
        moving = np.linalg.norm(residual, axis=1) > TOLERANCE
        active, residual, jacobian = active[moving], residual[moving], jacobian[moving]
        if not active.size:
            break
        jacobian_t = jacobian.mT
        step = np.linalg.solve(jacobian_t @ jacobian + eye, jacobian_t @ residual[..., None])
        updated = q[active] - step[..., 0]
        if bounded:
            updated = np.clip(updated, robot.lower, robot.upper)
        stalled = np.all(np.abs(updated - q[active]) < 1e-15, axis=1)
        q[active] = updated
        active = active[~stalled]
    residual, _ = passes.residual(q, target)
    return q, np.linalg.norm(residual, axis=1)


def _seeds(robot: Robot, count: int) -> np.ndarray:
    """``count`` seeds spread over the joint-limit box (5 % in from each side) by Roberts'
    low-discrepancy sequence R_n: u_i = (1/2 + i α) mod 1, α_j = φ^(−j), φ the root > 1 of
    φ^(n+1) = φ + 1 (the golden ratio for n = 1). Deterministic, and it spares every process
    the fifth of a second SciPy's quasi-Monte Carlo module takes to import."""
    n = robot.n
    phi = 2.0
    for _ in range(40):  # φ ← (1 + φ)^(1/(n+1)), a contraction (slope < 1/3): to rounding
        phi = (1 + phi) ** (1 / (n + 1))
    alpha = phi ** -np.arange(1.0, n + 1)
    unit = (0.5 + np.outer(np.arange(1, count + 1), alpha)) % 1
    lower, upper = robot.span
    return lower + (upper - lower) * (0.05 + 0.9 * unit)


def _point(robot: Robot, point) -> np.ndarray:
    point = np.asarray(point, dtype=float)
    if point.shape != (robot.m,) or not np.all(np.isfinite(point)):
        raise InvalidInputError(
            f"task point must be {robot.m} finite numbers (axes {robot.task_axes}); got {point}"
        )
    return point


def inverse_kinematics(
    robot: Robot,
    point: np.ndarray,
    held: str | Sequence[str],
    values: ArrayLike,
    seeds: int = 8,
) -> InverseKinematics:
    """Configurations reaching ``point`` (m,) with actuators ``held`` at ``values`` (k, r),
    each from ``seeds`` starts (at most `MOST_SEEDS`)."""
    if not is_whole(seeds, 1, MOST_SEEDS):
        raise InvalidInputError(
            f"seeds must be a whole number within [1, {MOST_SEEDS}]; got {seeds!r}"
        )
    point = _point(robot, point)
    rows = held_indices(robot, held)
    given = values
    try:
        values = np.atleast_2d(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        values = np.array([[np.nan]])
    if values.ndim != 2 or values.shape[1] != len(rows) or not np.all(np.isfinite(values)):
        raise InvalidInputError(
            f"held values must be finite numbers, shape (k, {len(rows)}); got {given!r}"
        )
    k, starts = len(values), _seeds(robot, seeds)
    guess = np.repeat(starts[None], k, axis=0).reshape(k * seeds, robot.n)
    target = np.concatenate([np.repeat(point[None], k, 0), values], axis=1)
    q, error = newton(robot, guess, rows, np.repeat(target, seeds, axis=0), ITERATIONS, True)
    error = error.reshape(k, seeds)
    per_seed = q.reshape(k, seeds, robot.n)
    converged = error < FOUND
    lower, upper = robot.span
    distance = np.linalg.norm((per_seed - (lower + upper) / 2) / (upper - lower), axis=2)
    choice = np.argmin(np.where(converged, distance, 1e6 + error), axis=1)
    picked = np.arange(k)
    reached = np.any(converged, axis=1)
    return InverseKinematics(per_seed[picked, choice], reached, error.min(axis=1))


def continue_held(
    robot: Robot,
    point: np.ndarray,
    row: int,
    known: tuple[np.ndarray, np.ndarray],
    values: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Configurations reaching ``point`` with the held actuator ``row`` at ``values`` (k,),
    Newton-continued from the found configurations ``known`` = (held values (j,), q (j, n))
    nearest each, and again from a nearer one whenever a pass finds one. The joint limits do not
    bind. Returns q (k, n) and the residuals (k,), in m (below `FOUND` where found)."""
    known_values, configurations = known
    q = np.empty((len(values), robot.n))
    residual = np.full(len(values), np.inf)
    tried = np.full(len(values), np.inf)  # distance of the value last continued from
    pending = np.arange(len(values))
    while pending.size:
        distance = np.abs(values[pending, None] - known_values[None])
        closer = distance.min(axis=1) < tried[pending]
        pending, nearest = pending[closer], np.argmin(distance, axis=1)[closer]
        if not pending.size:
            break
        tried[pending] = np.abs(values[pending] - known_values[nearest])
        target = np.concatenate(
            [np.broadcast_to(point, (pending.size, robot.m)), values[pending, None]], axis=1
        )
        q[pending], residual[pending] = newton(
            robot, configurations[nearest], [row], target, CONTINUATION_ITERATIONS
        )
        done = residual[pending] < FOUND
        known_values = np.concatenate([known_values, values[pending[done]]])
        configurations = np.concatenate([configurations, q[pending[done]]])
        pending = pending[~done]
    return q, residual


def configuration_at(robot: Robot, point: np.ndarray, held: dict[str, float]) -> np.ndarray:
    """The configuration (n,) reaching ``point`` with actuators held at ``held`` {name: value}.

    Raises `UnreachableError` with the distance by which the point is missed (in mm, the held
    values in mm or degrees).
    """
    if not isinstance(held, dict):
        raise InvalidInputError(f"held must be {{actuator: value}}; got {held!r}")
    solution = inverse_kinematics(robot, point, list(held), [list(held.values())])
    for name, value in held.items():
        actuator = robot.actuators[name]
        if not actuator.lower <= value <= actuator.upper:
            unit = actuator.unit
            raise UnreachableError(
                f"{name} = {amount(value, unit)} is outside its stroke "
                f"[{amount(actuator.lower, unit)}, {amount(actuator.upper, unit)}]"
            )
    if not solution.reached[0]:
        miss = _closest_miss(robot, np.asarray(point, dtype=float), held, solution.q[0])
        values = ", ".join(f"{k} = {amount(v, robot.actuators[k].unit)}" for k, v in held.items())
        raise UnreachableError(
            f"{robot.name} cannot reach task point {np.asarray(point).tolist()} with {values} "
            f"inside its joint limits: the closest configuration misses it by {amount(miss, 'm')}"
        )
    return solution.q[0]


def _closest_miss(robot: Robot, point: np.ndarray, held: dict[str, float], q0: np.ndarray):
    """min |y(q) − y*| over the joint-limit box with the held actuators at their values (held
    by a heavy penalty), by bounded least squares, in m."""
    from scipy.optimize import least_squares

    passes = _Passes(robot, held_indices(robot, list(held)))
    target = np.concatenate([point, list(held.values())])[None]
    weight = np.concatenate([np.ones(robot.m), np.full(len(held), 1e4)])

    def residual(q):
        return weight * passes.residual(q[None], target)[0][0]

    def jacobian(q):
        return weight[:, None] * passes.residual(q[None], target)[1][0]

    fits = [
        least_squares(residual, start, jac=jacobian, bounds=(robot.lower, robot.upper))
        for start in [q0, *_seeds(robot, 8)]
    ]
    return min(float(np.linalg.norm(fit.fun[: robot.m])) for fit in fits)


PATH_POINTS = 17  # points of a segment whose reach `check_path` checks
PATH_TOLERANCE = 1e-4  # m: a path missed by less is left to the motion's own limits


def check_path(robot: Robot, segment: Segment, seeds: int = 8) -> None:
    """Refuse, before any simulation, a segment some point of which no configuration inside
    the joint limits reaches: `UnreachableError` naming the point, its time and the distance
    it is missed by. The held actuators are free here.

    ``PATH_POINTS`` points y_d(t) from start to end are solved in order, each by projected
    Gauss-Newton on y(q) = y_d from every configuration found for the point before (from
    ``seeds`` spread over the joint box for the first, and again wherever continuation
    misses), so a reachable path is followed through its workspace and only a point that every
    seed misses by more than `PATH_TOLERANCE` is refused, and so is a start where the tool
    cannot move along some task direction (`_check_mobility`)."""
    times = np.linspace(0.0, segment.duration, PATH_POINTS)
    fresh = _seeds(robot, seeds)
    q = fresh
    for i, (t, point) in enumerate(zip(times, segment.position(times))):
        q, miss = newton(
            robot, q, [], np.broadcast_to(point, q.shape[:1] + point.shape), ITERATIONS, True
        )
        if not miss.min() < FOUND:
            target = np.broadcast_to(point, (len(fresh), robot.m))
            q, miss = newton(robot, fresh, [], target, ITERATIONS, True)
        if not miss.min() < PATH_TOLERANCE:
            best = q[np.argmin(miss)][None]
            error = robot.task_point(robot.kinematics(best))[0][0] - point
            raise UnreachableError(
                f"{robot.name} cannot follow segment {segment.name}: its point "
                f"{_point_text(robot, point)} (t = {t:.3g} s) is out of reach inside the joint "
                f"limits, missed by {_miss_text(robot, error)}"
            )
        q = q[miss < FOUND] if np.any(miss < FOUND) else q
        if not i:
            _check_mobility(robot, segment, q)


def _point_text(robot: Robot, y: np.ndarray) -> str:
    """A task point y (m,) as messages show it: its position in m, and the tool's angle in
    degrees where the task has one."""
    size = len(robot.task_axes)
    text = str(np.round(y[:size], 6).tolist())
    return text if size == robot.m else f"{text} at {amount(float(y[size]), 'rad')}"


def _miss_text(robot: Robot, error: np.ndarray) -> str:
    """How far a task point is missed, by error (m,): in mm, and in degrees of the tool's
    angle where the task has one."""
    size = len(robot.task_axes)
    text = amount(float(np.linalg.norm(error[:size])), "m")
    if size == robot.m:
        return text
    return f"{text} in position and {amount(abs(float(error[size])), 'rad')} in angle"


def _check_mobility(robot: Robot, segment: Segment, q: np.ndarray) -> None:
    """Refuse the start of ``segment`` if at every configuration q (k, n) found for it the task
    Jacobian J (m × n, Eq. 7) loses rank, σ_min < `SINGULAR_TOLERANCE` σ_max: the tool cannot
    move along some task direction there (or ever, for a task axis the robot does not move
    along), which no law can resolve."""
    _, J = robot.task_point(robot.kinematics(q))
    u, sigma, _ = np.linalg.svd(J)
    able = sigma[:, -1] > SINGULAR_TOLERANCE * sigma[:, 0]
    if able.any():
        return
    best = int(np.argmax(sigma[:, -1] / np.maximum(sigma[:, 0], np.finfo(float).tiny)))
    direction = u[best, :, -1]
    axes = task_labels(robot)
    along = (
        axes[int(np.argmax(np.abs(direction)))]
        if np.abs(direction).max() > 0.99
        else (f"{np.round(direction, 3).tolist()} (in {', '.join(axes)})")
    )
    raise SingularConfigurationError(
        f"{robot.name} cannot move its tool along {along} at the start of segment "
        f"{segment.name} {np.round(segment.start, 6).tolist()}: the task Jacobian J has rank "
        f"{int(np.sum(sigma[best] > SINGULAR_TOLERANCE * sigma[best, 0]))} of {robot.m} there; "
        f"task axes: {', '.join(axes)}"
    )
