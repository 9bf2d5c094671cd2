"""Choosing the start of a motion: a fixed start, or the paper's improved initial configuration.

The improved method (section 2, steps i-v): sample the held actuator (x3init) over its stroke;
for each value find the initial configuration by inverse kinematics, simulate the
pseudoinverse solution along the segment, keep the values whose motion stays inside the actuator
limits the whole way, and return the one with the lowest peak of the objective. All samples run
as one batch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.ik import held_indices, inverse_kinematics
from redundancy.objectives import Objective
from redundancy.robot import Robot
from redundancy.simulate import TIME_STEP, Trajectory, Violation, simulate
from redundancy.tasks import Segment


@dataclass(frozen=True)
class Sample:
    """One start of the search: held actuator ``value`` (m), the objective's ``peak`` (None if
    the start was unreachable), whether every checked limit held, and why not."""

    value: float
    peak: float | None
    feasible: bool
    violations: tuple[Violation, ...] = ()
    reason: str | None = None


@dataclass(frozen=True)
class SearchResult:
    """Every sample of a search along one segment, and the motions of the reachable ones.

    ``trajectory`` holds one motion per reachable sample; ``rows[i]`` is sample i's row there
    (−1 when unreachable).
    """

    segment: Segment
    objective: Objective
    held: str
    samples: tuple[Sample, ...]
    trajectory: Trajectory
    rows: np.ndarray

    @property
    def values(self) -> np.ndarray:
        return np.array([s.value for s in self.samples])

    @property
    def feasible(self) -> list[Sample]:
        return [s for s in self.samples if s.feasible]

    @property
    def feasible_range(self) -> tuple[float, float] | None:
        """The smallest and largest feasible sampled value, or None if there is none."""
        values = [s.value for s in self.feasible]
        return (min(values), max(values)) if values else None

    @property
    def best(self) -> Sample | None:
        """The feasible sample with the lowest peak (step v), or None."""
        feasible = self.feasible
        return min(feasible, key=lambda s: s.peak) if feasible else None  # type: ignore[arg-type,return-value]

    @property
    def closest_violation(self) -> Violation | None:
        """When nothing is feasible: the smallest worst-excess among the reachable samples."""
        worst = [max(s.violations, key=lambda v: v.excess) for s in self.samples if s.violations]
        return min(worst, key=lambda v: v.excess) if worst else None

    def motion(self, sample: Sample) -> Trajectory:
        """The motion of one reachable sample, as a trajectory of one."""
        row = int(self.rows[self.samples.index(sample)])
        if row < 0:
            raise InvalidInputError(f"the start {self.held} = {sample.value:g} is unreachable")
        return self.trajectory.select([row])


def sweep_values(robot: Robot, held: str, samples: int) -> np.ndarray:
    """``samples`` values evenly over the held actuator's stroke (step iii), (samples,)."""
    if samples < 1:
        raise InvalidInputError(f"samples must be at least 1; got {samples}")
    actuator = robot.actuators[held] if held in robot.actuators.names else None
    if actuator is None:
        raise InvalidInputError(
            f"unknown actuator {held!r}; actuators: {', '.join(robot.actuators.names)}"
        )
    if not np.isfinite(actuator.upper - actuator.lower):
        raise InvalidInputError(f"actuator {held!r} has no finite stroke to sample")
    if samples == 1:
        return np.array([(actuator.lower + actuator.upper) / 2])
    return np.linspace(actuator.lower, actuator.upper, samples)


def evaluate_starts(
    robot: Robot,
    segment: Segment,
    objective: Objective,
    held: str,
    values: np.ndarray,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: Callable[[int], None] | None = None,
) -> SearchResult:
    """Steps iv-v for the given held values (k,): IK, simulate, check the limits, take peaks."""
    held_indices(robot, [held])
    values = np.asarray(values, dtype=float)
    ik = inverse_kinematics(robot, segment.start, [held], values[:, None])
    reachable = np.flatnonzero(ik.reached)
    rows = np.full(len(values), -1)
    rows[reachable] = np.arange(reachable.size)
    if not reachable.size:
        raise UnreachableError(
            f"{robot.name} cannot reach the start {segment.start.tolist()} of segment "
            f"{segment.name} with {held} anywhere in [{values.min():g}, {values.max():g}]; the "
            f"closest configuration misses it by {ik.miss.min():.4g} m"
        )
    trajectory = simulate(
        robot,
        objective.resolver,
        segment,
        ik.q[reachable],
        time_step=time_step,
        checked=checked,
        progress=progress,
    )
    peaks = objective.peak(trajectory)
    samples = []
    for value, row, miss in zip(values, rows, ik.miss):
        if row < 0:
            reason = f"start unreachable (misses by {miss:.3g} m)"
            samples.append(Sample(float(value), None, False, (), reason))
            continue
        violations = tuple(trajectory.violations(row))
        failed = bool(trajectory.failed[row])
        feasible = bool(trajectory.within_limits[row])
        reason = "singular actuator Jacobian" if failed else None
        if violations:
            reason = str(max(violations, key=lambda v: v.excess))
        samples.append(Sample(float(value), float(peaks[row]), feasible, violations, reason))
    return SearchResult(segment, objective, held, tuple(samples), trajectory, rows)


def improved_start(
    robot: Robot,
    segment: Segment,
    objective: Objective,
    held: str = "x3",
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: Callable[[int], None] | None = None,
) -> SearchResult:
    """The paper's improved initial configuration (steps i-v) by a uniform sweep of ``held``.

    ``checked`` restricts the limit check to named actuators (the paper's step iv checks x1
    and x2); by default every actuator counts.
    """
    values = sweep_values(robot, held, samples)
    return evaluate_starts(robot, segment, objective, held, values, checked, time_step, progress)


def default_start(robot: Robot, segment: Segment, held: str = "x3", candidates: int = 101):
    """The documented default start: the held actuator at mid-stroke or, where the segment's
    start is out of reach there, at the reachable value nearest mid-stroke.

    Returns (value, q (n,)).
    """
    values = sweep_values(robot, held, candidates)
    middle = (values[0] + values[-1]) / 2
    order = np.argsort(np.abs(values - middle), kind="stable")
    ik = inverse_kinematics(robot, segment.start, [held], values[order, None])
    if not ik.reached.any():
        raise UnreachableError(
            f"{robot.name} cannot reach the start {segment.start.tolist()} of segment "
            f"{segment.name} with any {held} in its stroke; the closest configuration misses it "
            f"by {ik.miss.min():.4g} m"
        )
    first = int(np.argmax(ik.reached))
    return float(values[order][first]), ik.q[first]
