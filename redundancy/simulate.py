"""Integration of a resolver along a segment, for a batch of starting configurations at once.

The joint state follows q̇ = A⁻¹ ẋ, with ẋ from the resolver for the task velocity with
closed-loop correction of the tracking error,

    ẏ = ẏ_d + K (y_d(t) − y(q))          (K in 1/s)

integrated by the classical Runge-Kutta method on a uniform grid. A start whose actuator
Jacobian turns singular or whose state stops being finite is frozen there and flagged
(`Trajectory.failed`), so one bad start never spoils the batch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from redundancy.actuator_space import actuator_space, singular
from redundancy.errors import InvalidInputError
from redundancy.resolvers import Resolver
from redundancy.robot import Robot
from redundancy.tasks import Segment

TIME_STEP = 0.01  # s
GAIN = 20.0  # K, 1/s
LIMIT_TOLERANCE = 1e-9  # m: strokes within this of a limit count as inside


@dataclass(frozen=True)
class Violation:
    """An actuator outside its stroke over [start, end] (s), at worst ``excess`` m past its
    ``bound`` ("lower" or "upper")."""

    actuator: str
    bound: str
    start: float
    end: float
    excess: float

    def __str__(self) -> str:
        return (
            f"{self.actuator} {self.excess * 1000:.4g} mm past its {self.bound} limit "
            f"over t = {self.start:.2f}-{self.end:.2f} s"
        )


@dataclass(frozen=True)
class Trajectory:
    """k motions along one segment, sampled at times t (T,).

    q (k, T, n) joints; x, x_dot (k, T, n) actuator strokes (m) and velocities (m/s); y (k, T, m)
    tool; failed (k,) starts frozen at a singular or non-finite state; checked: the actuators
    whose stroke limits count for `within_limits`.
    """

    robot: Robot = field(repr=False)
    segment: Segment
    resolver: Resolver
    t: np.ndarray
    q: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    y: np.ndarray
    failed: np.ndarray
    checked: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.q)

    def concatenated(self, other: Trajectory) -> Trajectory:
        """These motions followed by ``other``'s (same robot, segment, resolver and grid)."""
        return replace(
            self,
            q=np.concatenate([self.q, other.q]),
            x=np.concatenate([self.x, other.x]),
            x_dot=np.concatenate([self.x_dot, other.x_dot]),
            y=np.concatenate([self.y, other.y]),
            failed=np.concatenate([self.failed, other.failed]),
        )

    def select(self, rows) -> Trajectory:
        """The motions ``rows`` alone."""
        rows = np.atleast_1d(rows)
        return replace(
            self,
            q=self.q[rows],
            x=self.x[rows],
            x_dot=self.x_dot[rows],
            y=self.y[rows],
            failed=self.failed[rows],
        )

    @cached_property
    def x_ddot(self) -> np.ndarray:
        """ẍ (k, T, n) in m/s², by second-order differences of ẋ in time."""
        return np.gradient(self.x_dot, self.t, axis=1, edge_order=2)

    @cached_property
    def tracking_error(self) -> np.ndarray:
        """|y(t) − y_d(t)| (k, T), in m."""
        return np.linalg.norm(self.y - self.segment.position(self.t), axis=2)

    @property
    def max_tracking_error(self) -> np.ndarray:
        """max_t |y − y_d| (k,), in m."""
        return self.tracking_error.max(axis=1)

    @cached_property
    def _states(self):
        """The actuator space at every sample, with q̇ = A⁻¹ ẋ, as one flat batch of k·T."""
        k, T, n = self.q.shape
        q = self.q.reshape(k * T, n)
        at_rest = actuator_space(self.robot, q, check=False)
        v = np.linalg.solve(at_rest.A, self.x_dot.reshape(k * T, n)[..., None])[..., 0]
        return actuator_space(self.robot, q, v, check=False)

    @cached_property
    def M_H(self) -> np.ndarray:
        """M_H (k, T, n, n) along the motion, kg."""
        k, T, n = self.q.shape
        return self._states.M_H.reshape(k, T, n, n)

    @cached_property
    def forces(self) -> np.ndarray:
        """Actuator forces F_H = M_H ẍ + N_H (k, T, n) (Eq. 21), N."""
        k, T, n = self.q.shape
        return self._states.forces(self.x_ddot.reshape(k * T, n)).reshape(k, T, n)

    @property
    def velocity_norm(self) -> np.ndarray:
        """ẋᵀẋ (k, T), m²/s²."""
        return np.sum(self.x_dot**2, axis=2)

    @property
    def kinetic(self) -> np.ndarray:
        """ẋᵀ M_H ẋ (k, T) = twice the kinetic energy (Eq. 28), J."""
        return np.einsum("kti,ktij,ktj->kt", self.x_dot, self.M_H, self.x_dot)

    @property
    def peak_velocity_norm(self) -> np.ndarray:
        """max_t ẋᵀẋ (k,), m²/s²."""
        return self.velocity_norm.max(axis=1)

    @property
    def peak_kinetic(self) -> np.ndarray:
        """max_t ẋᵀ M_H ẋ (k,), J."""
        return self.kinetic.max(axis=1)

    @cached_property
    def _checked_rows(self) -> list[int]:
        return [self.robot.actuators.names.index(name) for name in self.checked]

    @cached_property
    def within_limits(self) -> np.ndarray:
        """Whether each motion keeps every checked actuator inside its stroke (k,) and did not
        fail."""
        rows = self._checked_rows
        lower = self.robot.actuators.lower[rows] - LIMIT_TOLERANCE
        upper = self.robot.actuators.upper[rows] + LIMIT_TOLERANCE
        x = self.x[:, :, rows]
        return np.all((x >= lower) & (x <= upper), axis=(1, 2)) & ~self.failed

    def violations(self, i: int) -> list[Violation]:
        """Every interval over which motion ``i`` has a checked actuator outside its stroke."""
        found = []
        actuators = self.robot.actuators
        for row in self._checked_rows:
            x = self.x[i, :, row]
            for bound, excess in (
                ("lower", actuators.lower[row] - x),
                ("upper", x - actuators.upper[row]),
            ):
                outside = excess > LIMIT_TOLERANCE
                edges = np.flatnonzero(np.diff(np.concatenate([[0], outside.astype(int), [0]])))
                for start, stop in zip(edges[::2], edges[1::2]):
                    found.append(
                        Violation(
                            actuators.names[row],
                            bound,
                            float(self.t[start]),
                            float(self.t[stop - 1]),
                            float(excess[start:stop].max()),
                        )
                    )
        return sorted(found, key=lambda v: v.start)


def time_grid(segment: Segment, time_step: float = TIME_STEP) -> np.ndarray:
    """Uniform sample times over the segment, at most ``time_step`` apart, (T,) in s."""
    steps = max(1, int(np.ceil(segment.duration / time_step - 1e-9)))
    return np.linspace(0.0, segment.duration, steps + 1)


def simulate(
    robot: Robot,
    resolver: Resolver,
    segment: Segment,
    starts: np.ndarray,
    time_step: float = TIME_STEP,
    gain: float = GAIN,
    checked: tuple[str, ...] | None = None,
    progress: Callable[[int], None] | None = None,
) -> Trajectory:
    """Integrate ``resolver`` along ``segment`` from every start (k, n) at once.

    ``checked`` names the actuators whose strokes count for `Trajectory.within_limits` (default
    all); ``progress`` is called with the number of time steps just done.
    """
    starts = robot.configuration(starts, "starts")
    if segment.start.shape != (robot.m,):
        raise InvalidInputError(
            f"segment {segment.name} has {segment.start.size} coordinates; {robot.name}'s task "
            f"has {robot.m} ({robot.task_axes})"
        )
    if not (time_step > 0 and gain >= 0):
        raise InvalidInputError("time_step must be > 0 s and gain ≥ 0 1/s")
    checked = tuple(robot.actuators.names if checked is None else checked)
    unknown = set(checked) - set(robot.actuators.names)
    if unknown:
        raise InvalidInputError(
            f"unknown actuators {sorted(unknown)}; actuators: {', '.join(robot.actuators.names)}"
        )
    t = time_grid(segment, time_step)
    h = t[1] - t[0]
    k, n = starts.shape
    failed = np.zeros(k, dtype=bool)

    def rates(time: float, q: np.ndarray):
        """q̇ (k, n) and ẋ (k, n) at time ``time``; frozen (zero) for failed starts."""
        space = actuator_space(robot, q, check=False)
        bad = ~np.all(np.isfinite(q), axis=1) | singular(space.A)
        failed[bad] = True
        y_dot = segment.velocity + gain * (segment.position(time) - space.y)
        x_dot = resolver.resolve(space, y_dot)
        A = np.where(failed[:, None, None], np.eye(n), space.A)
        q_dot = np.linalg.solve(A, x_dot[..., None])[..., 0]
        failed[~np.all(np.isfinite(q_dot), axis=1)] = True
        q_dot[failed], x_dot[failed] = 0.0, 0.0
        return q_dot, x_dot, space.x, space.y

    q = np.empty((k, len(t), n))
    x, x_dot, y = np.empty_like(q), np.empty_like(q), np.empty((k, len(t), robot.m))
    q[:, 0] = starts
    for i, time in enumerate(t[:-1]):
        k1, x_dot[:, i], x[:, i], y[:, i] = rates(time, q[:, i])
        k2 = rates(time + h / 2, q[:, i] + h / 2 * k1)[0]
        k3 = rates(time + h / 2, q[:, i] + h / 2 * k2)[0]
        k4 = rates(time + h, q[:, i] + h * k3)[0]
        q[:, i + 1] = q[:, i] + np.where(failed[:, None], 0.0, h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
        if progress is not None:
            progress(1)
    _, x_dot[:, -1], x[:, -1], y[:, -1] = rates(t[-1], q[:, -1])
    return Trajectory(robot, segment, resolver, t, q, x, x_dot, y, failed.copy(), checked)
