"""Inverse kinematics: a configuration that puts the tool at a task point with chosen actuators
held at chosen values (the paper's step iv: the initial configuration from x3init).

With r held actuators and m task coordinates, r = n − m makes the system square:

    h1(q) = y*   (Eq. 6, m equations)      x_h(q) = x_h*   (Eq. 10, r equations)

It is solved on the Pinocchio model by Levenberg-Marquardt steps projected onto the joint limits,
from several seeds spread over the joint-limit box, for a whole batch of held values at once. Of
the solutions found inside the limits, the branch nearest the middle of the joint ranges is kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.robot import Robot

TOLERANCE = 1e-12  # m (and m or rad for held actuators): a residual this small has converged
ITERATIONS = 40
DAMPING = 1e-10


@dataclass(frozen=True)
class InverseKinematics:
    """Solutions for k held values: q (k, n); reached (k,) whether the point was reached inside
    the joint limits; miss (k,) the smallest residual |[y − y*, x_h − x_h*]| found, in m."""

    q: np.ndarray
    reached: np.ndarray
    miss: np.ndarray


def _seeds(robot: Robot, count: int) -> np.ndarray:
    """``count`` seeds spread over the joint-limit box (a scrambled Halton design, fixed seed)."""
    from scipy.stats import qmc

    unit = qmc.Halton(d=robot.n, scramble=True, seed=7).random(count)
    return robot.lower + (robot.upper - robot.lower) * (0.05 + 0.9 * unit)


def held_indices(robot: Robot, held: list[str] | tuple[str, ...]) -> list[int]:
    """Rows of the held actuators, checking there are exactly n − m of them."""
    names = robot.actuators.names
    unknown = [h for h in held if h not in names]
    if unknown:
        raise InvalidInputError(f"unknown actuators {unknown}; actuators: {', '.join(names)}")
    if len(held) != robot.n - robot.m:
        raise InvalidInputError(
            f"{robot.name} has n − m = {robot.n - robot.m} redundant degrees; hold that many "
            f"actuators (got {list(held)}; actuators: {', '.join(names)})"
        )
    return [names.index(h) for h in held]


def inverse_kinematics(
    robot: Robot,
    point: np.ndarray,
    held: list[str] | tuple[str, ...],
    values: np.ndarray,
    seeds: int = 8,
) -> InverseKinematics:
    """Configurations reaching ``point`` (m,) with actuators ``held`` at ``values`` (k, r)."""
    point = np.asarray(point, dtype=float)
    if point.shape != (robot.m,) or not np.all(np.isfinite(point)):
        raise InvalidInputError(
            f"task point must be {robot.m} finite numbers (axes {robot.task_axes}); got {point}"
        )
    rows = held_indices(robot, held)
    values = np.atleast_2d(np.asarray(values, dtype=float))
    if values.shape[1] != len(rows) or not np.all(np.isfinite(values)):
        raise InvalidInputError(f"held values must be finite, shape (k, {len(rows)})")
    k, starts = len(values), _seeds(robot, seeds)
    q = np.repeat(starts[None], k, axis=0).reshape(k * seeds, robot.n)
    target = np.concatenate([np.repeat(point[None], k, 0), values], axis=1)
    target = np.repeat(target, seeds, axis=0)
    active = np.arange(len(q))  # rows still moving towards a solution
    for _ in range(ITERATIONS):
        residual, jacobian = _residual(robot, q[active], rows, target[active])
        moving = np.linalg.norm(residual, axis=1) > TOLERANCE
        active, residual, jacobian = active[moving], residual[moving], jacobian[moving]
        if not active.size:
            break
        jacobian_t = np.swapaxes(jacobian, 1, 2)
        normal = jacobian_t @ jacobian + DAMPING * np.eye(robot.n)
        step = np.linalg.solve(normal, jacobian_t @ residual[..., None])[..., 0]
        updated = np.clip(q[active] - step, robot.lower, robot.upper)
        stalled = np.all(np.abs(updated - q[active]) < 1e-15, axis=1)
        q[active] = updated
        active = active[~stalled]
    residual, _ = _residual(robot, q, rows, target)
    error = np.linalg.norm(residual, axis=1).reshape(k, seeds)
    per_seed = q.reshape(k, seeds, robot.n)
    converged = error < 1e3 * TOLERANCE
    middle = (robot.lower + robot.upper) / 2
    distance = np.linalg.norm((per_seed - middle) / (robot.upper - robot.lower), axis=2)
    choice = np.argmin(np.where(converged, distance, 1e6 + error), axis=1)
    picked = np.arange(k)
    return InverseKinematics(per_seed[picked, choice], converged.any(axis=1), error.min(axis=1))


def _residual(robot: Robot, q: np.ndarray, rows: list[int], target: np.ndarray):
    kinematics = robot.kinematics(q)
    task = robot.task(kinematics)
    x, A = robot.actuators.evaluate(kinematics)
    residual = np.concatenate([task.position, x[:, rows]], axis=1) - target
    return residual, np.concatenate([task.jacobian, A[:, rows]], axis=1)


def configuration_at(robot: Robot, point: np.ndarray, held: dict[str, float]) -> np.ndarray:
    """The configuration (n,) reaching ``point`` with actuators held at ``held`` {name: value}.

    Raises `UnreachableError` with the distance by which the point is missed.
    """
    solution = inverse_kinematics(robot, point, list(held), np.array([list(held.values())]))
    if not solution.reached[0]:
        miss = _closest_miss(robot, np.asarray(point, dtype=float), held, solution.q[0])
        raise UnreachableError(
            f"{robot.name} cannot reach task point {np.asarray(point).tolist()} with "
            f"{', '.join(f'{k} = {v:g}' for k, v in held.items())} inside its joint limits: "
            f"the closest configuration misses it by {miss:.4g} m"
        )
    return solution.q[0]


def _closest_miss(robot: Robot, point: np.ndarray, held: dict[str, float], q0: np.ndarray):
    """min |y(q) − y*| over the joint-limit box with the held actuators at their values (held
    by a heavy penalty), by bounded least squares, in m."""
    from scipy.optimize import least_squares

    rows = held_indices(robot, list(held))
    target = np.concatenate([point, list(held.values())])[None]
    weight = np.concatenate([np.ones(robot.m), np.full(len(rows), 1e4)])

    def residual(q):
        return weight * _residual(robot, q[None], rows, target)[0][0]

    def jacobian(q):
        return weight[:, None] * _residual(robot, q[None], rows, target)[1][0]

    fits = [
        least_squares(residual, start, jac=jacobian, bounds=(robot.lower, robot.upper))
        for start in [q0, *_seeds(robot, 8)]
    ]
    return min(float(np.linalg.norm(fit.fun[: robot.m])) for fit in fits)
