"""Inverse kinematics: a configuration that puts the tool at a task point with chosen actuators
held at chosen values (the paper's step iv: the initial configuration from x3init).

With r held actuators and m task coordinates, r = n − m makes the system square:

    h1(q) = y*   (Eq. 6, m equations)      x_h(q) = x_h*   (Eq. 10, r equations)

One routine solves it, for a batch at once (`newton`); `inverse_kinematics` runs it from seeds
spread over the joint-limit box, `continue_held` from configurations found at nearby held values.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache, partial
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from redundancy import _core
from redundancy.errors import (
    InvalidInputError,
    SingularConfigurationError,
    UnreachableError,
    placed,
)
from redundancy.model.actuators import ActuatorSet
from redundancy.model.robot import Robot, require_robot
from redundancy.model.values import is_real, is_whole
from redundancy.planning.angles import task_labels
from redundancy.planning.tasks import Segment
from redundancy.resolution.limits import amount
from redundancy.resolution.state import SINGULAR_TOLERANCE, ActuatorSpace, evaluate

TOLERANCE = 1e-12  # m (and m or rad for held actuators): a residual this small has converged
FOUND = 1e3 * TOLERANCE  # a residual below this has found a configuration
ITERATIONS = 40  # from a seed far away
CONTINUATION_ITERATIONS = 10  # from a configuration nearby, Newton converges in about 4
DAMPING = 1e-10
STALLED = 1e-12  # m or rad: a step this small no longer moves a row: it has converged (its
# residual is then far below FOUND) or, clipped to the joint limits, it is stuck in a corner
SAME_POSE = 1e-6  # m or rad: configurations Newton found this close are one pose
MOST_SEEDS = 1000  # starts per point of inverse_kinematics: each is a Newton solve per value


@dataclass(frozen=True)
class InverseKinematics:
    """Solutions for k held values: q (k, n); reached (k,) whether the point was reached inside
    the joint limits; miss (k,) the smallest residual |[y − y*, x_h − x_h*]| found, in m."""

    q: np.ndarray
    reached: np.ndarray
    miss: np.ndarray


def require_redundancy(robot: Robot) -> None:
    """One line where ``robot`` has no redundancy to resolve: n ≤ m."""
    if robot.n <= robot.m:
        bare = robot.actuators.source.lower().endswith((".urdf", ".xacro"))  # no robot.toml
        where = "a robot.toml that names its URDF" if bare else "its robot.toml"
        raise InvalidInputError(
            f"{robot.name} has n = {robot.n} joints for a task of m = {robot.m} coordinates "
            f"(tool {robot.task_axes}): no redundancy to resolve; give fewer task_axes in "
            f'{where} (e.g. task_axes = "xz" for a planar task), or to load_robot'
        )


def held_indices(robot: Robot, held: str | Sequence[str]) -> list[int]:
    """Rows of the held actuators (one name, or several), checking there are exactly n − m."""
    require_redundancy(robot)
    rows = robot.actuators.rows(held)
    if len(rows) != robot.n - robot.m:
        raise InvalidInputError(
            f"{robot.name} has n − m = {robot.n - robot.m} redundant degrees; hold that many "
            f"actuators (got {held!r}; actuators: {', '.join(robot.actuators.names)})"
        )
    return rows


def named_values(robot: Robot, held, values) -> str:
    """The held actuators' values by name, in mm or degrees: "x3 = 812.3 mm"."""
    return ", ".join(f"{h} = {amount(v, robot.actuators[h].unit)}" for h, v in zip(held, values))


def held_names(robot: Robot, held: str | Sequence[str]) -> tuple[str, ...]:
    """The held actuators (one name, or several) as a tuple of names, checked as
    `held_indices` checks them."""
    return tuple(robot.actuators.names[row] for row in held_indices(robot, held))


class Solved(NamedTuple):
    """Newton's answer: q (k, n), the residuals |[y − y*, x_h − x_h*]| (k,) in m (and rad),
    where it read every actuator the states at q, and the side of the fold at q (`fold_side`,
    from the K its last pass read; 0 where K is not square)."""

    q: np.ndarray
    miss: np.ndarray
    space: ActuatorSpace | None
    side: np.ndarray


def newton(
    robot: Robot,
    guess: np.ndarray,
    rows: list[int],
    target: np.ndarray,
    iterations: int,
    bounded: bool = False,
    start: ActuatorSpace | None = None,
) -> Solved:
    """Damped Gauss-Newton on [y(q); x_h(q)] = target (k, n) from ``guess`` (k, n): steps
    δ = (KᵀK + δ₀ I)⁻¹ Kᵀ r with K = [J; A_h] (Eqs. 7, 11), each iterate clipped to the joint
    limits when ``bounded`` (a projected Levenberg-Marquardt), a joint at a limit the step would
    carry past it held there and δ solved again without its column of K, so that a point the
    tool reaches only with a joint at its limit is reached in a few steps. A row stops once its
    residual is below `TOLERANCE` or its step no longer moves it (`STALLED`).

    Each configuration is evaluated once: a row keeps the residual and K of its latest iterate,
    and the rows of a pass at one configuration (the seeds every target starts from, a corner
    of the joint box) share it. A pass reads the task and the held actuators alone; given
    ``start``, the states at ``guess`` evaluated already, Newton begins from them and reads
    every actuator, and the states at its solution come back for whoever reads them next.

    The loop is the core's (`redundancy._core.newton`), on the compiled pass of the task and
    the held actuators (`Robot.held_pass`), or on a Python one: for a kind or a task of your
    own, and with ``start``, whose states are kept."""
    part = robot.actuators.part(rows)
    parts: list[ActuatorSpace] = [] if start is None else [start]  # every pass's states

    def held(unique: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _held_pass(robot, part, unique)

    def evaluated(unique: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        space = evaluate(robot, unique)
        parts.append(space)
        return _read(space, rows)

    arguments = (
        np.asarray(guess, dtype=float),
        target,
        None if start is None else _read(start, rows),
        iterations,
        bounded,
        robot.lower,
        robot.upper,
        TOLERANCE,
        DAMPING,
        STALLED,
    )
    compiled = robot.held_pass(part) if start is None else None
    found = None if compiled is None else _core.newton(compiled, *arguments)
    if found is None:  # a kind or a task of your own, a state a kind refused, or the states kept
        found = _core.newton(held if start is None else evaluated, *arguments)
    q, miss, latest, side = found
    space = None if start is None else ActuatorSpace.joined(parts).take(latest)
    return Solved(q, miss, space, side)


def _held_pass(robot: Robot, part: ActuatorSet, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[y; x_h] (k, m + r) and K = [J; A_h] (k, m + r, n) at q (k, n), by a pass that reads the
    task and the held actuators ``part`` alone."""
    kinematics = robot.kinematics(q, actuators=part)
    (x, A), (y, J) = part.evaluate(kinematics), robot.task_point(kinematics)
    return np.concatenate([y, x], axis=1), np.concatenate([J, A], axis=1)


def _read(space: ActuatorSpace, rows: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """[y; x_h] and K = [J; A_h] of the held actuators ``rows`` at evaluated states."""
    value = np.concatenate([space.y, space.x[:, rows]], axis=1)
    return value, np.concatenate([space.J, space.A[:, rows]], axis=1)


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


def inverse_kinematics(
    robot: Robot,
    point: np.ndarray,
    held: str | Sequence[str],
    values: ArrayLike,
    seeds: int = 8,
) -> InverseKinematics:
    """Configurations reaching ``point`` (m,) with actuators ``held`` at ``values`` (k, r),
    each from ``seeds`` starts (at most `MOST_SEEDS`)."""
    require_robot(robot)
    if not is_whole(seeds, 1, MOST_SEEDS):
        raise InvalidInputError(
            f"seeds must be a whole number within [1, {MOST_SEEDS}]; got {seeds!r}"
        )
    point = np.asarray(point, dtype=float)
    if point.shape != (robot.m,) or not np.all(np.isfinite(point)):
        raise InvalidInputError(
            f"task point must be {robot.m} finite numbers (axes {robot.task_axes}); got {point}"
        )
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
    per_seed, error, order, _ = _from_seeds(robot, point, rows, values, seeds)
    picked = per_seed[np.arange(len(values)), order[:, 0]]
    return InverseKinematics(picked, np.any(error < FOUND, axis=1), error.min(axis=1))


def _from_seeds(robot: Robot, point: np.ndarray, rows: list[int], values: np.ndarray, seeds: int):
    """Newton from ``seeds`` starts for each of the held ``values`` (k, r): the configurations
    (k, seeds, n), their residuals (k, seeds), per value the seeds in order of preference (the
    converged ones nearest the joint box's middle first, then the others by residual), and the
    sides of the fold (k, seeds) Newton read at the configurations (`newton`; 0 where
    K = [J; A_h] is not square)."""
    k, starts = len(values), _seeds(robot, seeds)
    guess = np.repeat(starts[None], k, axis=0).reshape(k * seeds, robot.n)
    target = np.concatenate([np.repeat(point[None], k, 0), values], axis=1)
    q, error, _, side = newton(
        robot, guess, rows, np.repeat(target, seeds, axis=0), ITERATIONS, True
    )
    error = error.reshape(k, seeds)
    per_seed = q.reshape(k, seeds, robot.n)
    lower, upper = robot.span
    distance = np.linalg.norm((per_seed - (lower + upper) / 2) / (upper - lower), axis=2)
    order = np.argsort(np.where(error < FOUND, distance, 1e6 + error), axis=1, kind="stable")
    return per_seed, error, order, side.reshape(k, seeds)


def assembly_branches(
    robot: Robot, point: np.ndarray, held: str | Sequence[str], values: ArrayLike, seeds: int = 8
) -> np.ndarray:
    """The distinct configurations (b, n) inside the joint limits that reach ``point`` (m,)
    with the actuators ``held`` at ``values`` (r,), one per assembly branch there (an arm's
    elbow up and elbow down), by Newton from ``seeds`` starts: the first the one
    `inverse_kinematics` picks, the others in its order of preference; none where no seed
    reaches the point. Two are one pose where no joint differs by more than `SAME_POSE` (a
    turning joint modulo a turn)."""
    q, *_ = every_configuration(robot, point, held, values, seeds)  # values: one row (r,)
    same = robot.same_poses(q[:, None], q[None], SAME_POSE)
    kept: list[int] = []
    for i in range(len(q)):
        if not same[i, kept].any():
            kept.append(i)
    return q[kept]


def every_configuration(
    robot: Robot, point: np.ndarray, held: str | Sequence[str], values: ArrayLike, seeds: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every configuration inside the joint limits that Newton from ``seeds`` starts finds
    reaching ``point`` (m,) with the actuators ``held`` at each of ``values`` (k, r), (j, n), the
    held values of each, (j, r), and the side of the fold of each (j,) (`fold_side`, as Newton
    read it there; 0 where K = [J; A_h] is not square): every assembly branch that some seed finds
    there, once per seed that found it, value by value, each value's in `inverse_kinematics`'
    order of preference (its pick first)."""
    rows = held_indices(robot, held)
    values = np.asarray(values, dtype=float).reshape(-1, len(rows))
    per_seed, error, order, sides = _from_seeds(
        robot, np.asarray(point, float), rows, values, seeds
    )
    each = np.arange(len(values))[:, None]
    found = error[each, order] < FOUND
    return (
        per_seed[each, order][found],
        np.repeat(values, seeds, axis=0)[found.ravel()],
        sides[each, order][found],
    )


def free_configurations(robot: Robot, point: np.ndarray, seeds: int) -> tuple[np.ndarray, float]:
    """Configurations (j, n) inside the joint limits that reach ``point`` (m,) with every
    actuator free, by Newton from ``seeds`` spread over the joint box (none where each misses),
    and the least distance by which a seed's configuration misses it, m."""
    target = np.broadcast_to(np.asarray(point, dtype=float), (seeds, robot.m))
    q, miss, *_ = newton(robot, _seeds(robot, seeds), [], target, ITERATIONS, True)
    return q[miss < FOUND], float(miss.min())


def fold_side(space: ActuatorSpace, rows: list[int]) -> np.ndarray:
    """The side of the fold each state of ``space`` lies on, sign det K with K = [J; A_h]
    (Eqs. 7, 11) for the held actuators ``rows``: (k,) of ±1. K is singular on the fold, where
    the configurations that reach a point with the held values meet (an arm's elbow up and
    elbow down, at the edge of its reach); followed along the held values, an assembly branch
    keeps its side."""
    return np.sign(np.linalg.det(np.concatenate([space.J, space.A[:, rows]], axis=1)))


def continue_held(
    robot: Robot,
    point: np.ndarray,
    row: int,
    known: tuple[np.ndarray, np.ndarray, np.ndarray],
    values: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Configurations reaching ``point`` with the held actuator ``row`` at ``values`` (k,),
    Newton-continued from the found configurations ``known`` = (held values (j,), q (j, n), their
    sides of the fold (j,)) nearest each, and again from a nearer one whenever a pass finds one.
    The joint limits do not bind. A configuration counts as found only on its origin's side of
    the fold (`fold_side`): Newton from far away can land on the other assembly branch, which
    continuation along the held value does not reach without crossing the fold (it tries again
    from a nearer one). Each revolute joint of a bounded range is then moved by whole turns to
    the turn inside its range, where one is, else to the turn nearest its origin (Newton from
    far away can land on the pose a turn or more away, outside the joint's range; and a slew
    whose stroke is one turn, crossing its end, comes back inside it a turn away), where the
    moved configuration still meets the point and the held value (one driven directly is not
    moved by a turn). Returns q (k, n), the residuals (k,), in m (below `FOUND` where found),
    and the sides (k,).

    The loop is the core's (`redundancy._core.continue_held`, on `newton`'s loop), on the
    compiled pass of the task and the held actuator, or on a Python one for a kind or a task of
    your own."""
    part = robot.actuators.part([row])
    arguments = (
        np.asarray(point, dtype=float),
        *(np.asarray(given, dtype=float) for given in known),
        np.asarray(values, dtype=float),
        CONTINUATION_ITERATIONS,
        robot.lower,
        robot.upper,
        robot.rotary_joints & ~robot.turning,
        TOLERANCE,
        DAMPING,
        STALLED,
        FOUND,
    )
    compiled = robot.held_pass(part)
    found = None if compiled is None else _core.continue_held(compiled, *arguments)
    if found is None:  # a kind or a task of your own, or a state a kind refused
        found = _core.continue_held(partial(_held_pass, robot, part), *arguments)
    return found


def configuration_at(robot: Robot, point: np.ndarray, held: dict[str, float]) -> np.ndarray:
    """The configuration (n,) reaching ``point`` with actuators held at ``held`` {name: value}.

    Raises `UnreachableError` with the distance by which the point is missed (in mm, the held
    values in mm or degrees).
    """
    require_robot(robot)
    if not isinstance(held, dict) or not all(is_real(v) for v in held.values()):
        raise InvalidInputError(f"held must be {{actuator: value}}, values numbers; got {held!r}")
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

    part = robot.actuators.part(held_indices(robot, list(held)))
    target = np.concatenate([point, list(held.values())])
    weight = np.concatenate([np.ones(robot.m), np.full(len(held), 1e4)])

    @lru_cache(maxsize=1)  # least squares asks for the residual, then K, at one q
    def at(key: bytes) -> tuple[np.ndarray, np.ndarray]:
        value, jacobian = _held_pass(robot, part, np.frombuffer(key)[None])
        return weight * (value[0] - target), weight[:, None] * jacobian[0]

    def residual(q):
        return at(q.tobytes())[0]

    def jacobian(q):
        return at(q.tobytes())[1]

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
    it is missed by, and the segment's end where that is out of reach too (the point a task
    file gives). The held actuators are free here.

    ``PATH_POINTS`` points y_d(t) from start to end are solved in order, each by projected
    Gauss-Newton on y(q) = y_d from every configuration found for the point before (from
    ``seeds`` spread over the joint box for the first, and again wherever continuation
    misses), so a reachable path is followed through its workspace and only a point that every
    seed misses by more than `PATH_TOLERANCE` is refused, and so is a start where the tool
    cannot move along some task direction (`_check_mobility`)."""
    times = np.linspace(0.0, segment.duration, PATH_POINTS)
    fresh = q = _seeds(robot, seeds)
    for i, (t, point) in enumerate(zip(times, segment.position(times))):
        for guess in (q, fresh):  # the seeds again wherever continuation misses
            target = np.broadcast_to(point, (len(guess), robot.m))
            q, miss, *_ = newton(robot, guess, [], target, ITERATIONS, True)
            if miss.min() < FOUND:
                break
        if not miss.min() < PATH_TOLERANCE:
            how = (
                f"{robot.name} cannot follow segment {segment.name}: its point "
                f"{_point_text(robot, point)} (t = {t:.3g} s) is out of reach inside the "
                f"joint limits, missed by {_miss_text(robot, _error(robot, q, miss, point))}"
            )
            if i < len(times) - 1:  # where the end the task gives is out of reach too, say so
                end = segment.position(times[-1:])[0]
                target = np.broadcast_to(end, (len(fresh), robot.m))
                q, miss, *_ = newton(robot, fresh, [], target, ITERATIONS, True)
                if not miss.min() < PATH_TOLERANCE:
                    how += (
                        f"; so is its end {_point_text(robot, end)}, missed by "
                        f"{_miss_text(robot, _error(robot, q, miss, end))}"
                    )
            raise UnreachableError(placed(segment.source, how))
        q = q[miss < FOUND] if np.any(miss < FOUND) else q
        if not i:
            _check_mobility(robot, segment, q)


def _error(robot: Robot, q: np.ndarray, miss: np.ndarray, point: np.ndarray) -> np.ndarray:
    """y − ``point`` (m,) at the configuration among q (k, n) that misses it least."""
    return robot.task_point(robot.kinematics(q[np.argmin(miss)][None]))[0][0] - point


def _point_text(robot: Robot, y: np.ndarray) -> str:
    """A task point y (m,) as messages show it: its position in m, and the tool's angle in
    degrees where the task has one."""
    size = len(robot.task_axes)
    text = f"{np.round(y[:size], 6).tolist()} m"
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
    rank = int(np.sum(sigma[best] > SINGULAR_TOLERANCE * sigma[best, 0]))
    raise SingularConfigurationError(
        placed(
            segment.source,
            f"{robot.name} cannot move its tool along {along} at the start of segment "
            f"{segment.name} {np.round(segment.start, 6).tolist()}: the task Jacobian J has rank "
            f"{rank} of {robot.m} there; task axes: {', '.join(axes)}",
        )
    )
