"""Choosing the start of a motion: a fixed start, or the paper's improved initial configuration.

The improved method (section 2, steps i-v): sample the held actuators (the crane's x3init) over
their strokes; for each sample find the initial configuration by inverse kinematics, simulate
the pseudoinverse solution along the segment, keep the samples whose motion stays inside the
actuator limits the whole way, and return the one with the lowest peak of the objective. All
samples of a round run as one batch.

With one held actuator (r = 1) the samples are the paper's uniform sweep. With r > 1 a uniform
grid costs samples^r, so the search spreads ``samples`` points over the stroke box with a
scrambled Halton design, then refines the best feasible ones by compass search: each round
tries every leader ± h along every held actuator (clipped to the strokes, one batch), moves a
leader to its best feasible improvement, and halves h when no leader improved, from
h = stroke / samples^(1/r) down to stroke / 1000.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.ik import held_indices, inverse_kinematics
from redundancy.objectives import Objective
from redundancy.resolvers import Resolver
from redundancy.robot import Robot
from redundancy.simulate import TIME_STEP, Trajectory, Violation, simulate
from redundancy.tasks import Segment, WorkCycle

REFINED_AROUND = 3  # best feasible samples the compass search refines (r > 1)
REFINEMENT_ROUNDS = 30  # at most, each one batch of REFINED_AROUND · 2r simulations
FINEST_STEP = 1e-3  # compass step at which refinement stops, as a fraction of each stroke


@dataclass(frozen=True)
class Sample:
    """One start of the search: the held actuators' ``values`` (m or rad), the objective's
    ``peak`` (None if the start was unreachable), whether every checked limit held, and why
    not."""

    values: tuple[float, ...]
    peak: float | None
    feasible: bool
    violations: tuple[Violation, ...] = ()
    reason: str | None = None

    @property
    def value(self) -> float:
        """The held value, for one held actuator."""
        if len(self.values) != 1:
            raise InvalidInputError(f"this sample holds {len(self.values)} actuators; use values")
        return self.values[0]


def _held(held: str | Sequence[str]) -> tuple[str, ...]:
    return (held,) if isinstance(held, str) else tuple(held)


class SampledStarts:
    """What a search over starts finds, from its ``samples``: the feasible ones, their range
    and the best (step v). Shared by the sweep's `SearchResult` and the fast search."""

    samples: tuple[Sample, ...]

    @property
    def feasible(self) -> list[Sample]:
        return [s for s in self.samples if s.feasible]

    @property
    def feasible_range(self) -> tuple[float, float] | None:
        """The smallest and largest feasible sampled value (one held actuator), or None."""
        values = [s.value for s in self.feasible]
        return (min(values), max(values)) if values else None

    @property
    def best(self) -> Sample | None:
        """The feasible sample with the lowest peak (step v), or None."""
        feasible = self.feasible
        return min(feasible, key=lambda s: s.peak) if feasible else None  # type: ignore[arg-type,return-value]


@dataclass(frozen=True)
class SearchResult(SampledStarts):
    """Every sample of a search along one segment, and the motions of the reachable ones.

    ``trajectory`` holds one motion per reachable sample; ``rows[i]`` is sample i's row there
    (−1 when unreachable).
    """

    segment: Segment
    objective: Objective
    held: tuple[str, ...]
    samples: tuple[Sample, ...]
    trajectory: Trajectory
    rows: np.ndarray

    @property
    def values(self) -> np.ndarray:
        """The samples' held values, (k, r)."""
        return np.array([s.values for s in self.samples])

    @property
    def feasible_box(self) -> np.ndarray | None:
        """Per held actuator, the smallest and largest feasible sampled value (r, 2), or None."""
        feasible = np.array([s.values for s in self.feasible])
        return np.stack([feasible.min(0), feasible.max(0)], axis=1) if feasible.size else None

    @property
    def closest_violation(self) -> Violation | None:
        """When nothing is feasible: the smallest worst-excess among the reachable samples."""
        worst = [max(s.violations, key=lambda v: v.excess) for s in self.samples if s.violations]
        return min(worst, key=lambda v: v.excess) if worst else None

    def motion(self, sample: Sample) -> Trajectory:
        """The motion of one reachable sample, as a trajectory of one."""
        row = int(self.rows[self.samples.index(sample)])
        if row < 0:
            raise InvalidInputError(f"the start {sample.values} of {self.held} is unreachable")
        return self.trajectory.select([row])

    def extended(self, other: SearchResult) -> SearchResult:
        """This search with the samples of ``other`` (same segment and objective) appended."""
        offset = len(self.trajectory)
        rows = np.concatenate([self.rows, np.where(other.rows < 0, -1, other.rows + offset)])
        return SearchResult(
            self.segment,
            self.objective,
            self.held,
            self.samples + other.samples,
            self.trajectory.concatenated(other.trajectory),
            rows,
        )


def held_actuators(robot: Robot, cycle: WorkCycle) -> tuple[str, ...]:
    """The actuators a search holds on ``cycle``: the task's ``held``, or the last n − m."""
    return cycle.held or tuple(robot.actuators.names[robot.m :])


def stroke_box(robot: Robot, held: tuple[str, ...]) -> np.ndarray:
    """The held actuators' strokes (r, 2), checked finite."""
    held_indices(robot, held)
    box = np.array([[robot.actuators[h].lower, robot.actuators[h].upper] for h in held])
    if not np.all(np.isfinite(box)):
        raise InvalidInputError(f"held actuators {list(held)} need finite strokes to sample")
    return box


def sweep_values(robot: Robot, held: str, samples: int) -> np.ndarray:
    """``samples`` values evenly over one held actuator's stroke (step iii), (samples,)."""
    if samples < 1:
        raise InvalidInputError(f"samples must be at least 1; got {samples}")
    lower, upper = stroke_box(robot, (held,))[0]
    if samples == 1:
        return np.array([(lower + upper) / 2])
    return np.linspace(lower, upper, samples)


def evaluate_starts(
    robot: Robot,
    segment: Segment,
    objective: Objective,
    held: str | Sequence[str],
    values: np.ndarray,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: Callable[[int], None] | None = None,
) -> SearchResult:
    """Steps iv-v for the given held values, (k,) for one held actuator or (k, r): IK,
    simulate, check the limits, take the peaks."""
    held = _held(held)
    held_indices(robot, held)
    values = np.asarray(values, dtype=float).reshape(-1, len(held))
    ik = inverse_kinematics(robot, segment.start, held, values)
    reachable = np.flatnonzero(ik.reached)
    rows = np.full(len(values), -1)
    rows[reachable] = np.arange(reachable.size)
    if not reachable.size:
        raise UnreachableError(
            f"{robot.name} cannot reach the start {segment.start.tolist()} of segment "
            f"{segment.name} from any of the {len(values)} sampled values of "
            f"{', '.join(held)}; the closest configuration misses it by {ik.miss.min():.4g} m"
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
        start = tuple(float(v) for v in value)
        if row < 0:
            unreachable = f"start unreachable (misses by {miss:.3g} m)"
            samples.append(Sample(start, None, False, (), unreachable))
            continue
        violations = tuple(trajectory.violations(row))
        reason = "singular actuator Jacobian" if trajectory.failed[row] else None
        if violations:
            reason = str(max(violations, key=lambda v: v.excess))
        feasible = bool(trajectory.within_limits[row])
        samples.append(Sample(start, float(peaks[row]), feasible, violations, reason))
    return SearchResult(segment, objective, held, tuple(samples), trajectory, rows)


def improved_start(
    robot: Robot,
    segment: Segment,
    objective: Objective,
    held: str | Sequence[str] = "x3",
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: Callable[[int], None] | None = None,
) -> SearchResult:
    """The paper's improved initial configuration (steps i-v), searching the held actuators.

    One held actuator: a uniform sweep of ``samples`` values. Several: ``samples`` Halton
    points, then compass-search refinement of the best feasible ones (see the module
    docstring). ``checked`` restricts the limit check to named actuators (the paper's step iv
    checks x1 and x2); by default every actuator counts.
    """
    held = _held(held)
    if samples < 1:
        raise InvalidInputError(f"samples must be at least 1; got {samples}")
    if len(held) == 1:
        values = sweep_values(robot, held[0], samples)
        return evaluate_starts(
            robot, segment, objective, held, values, checked, time_step, progress
        )
    from scipy.stats import qmc

    box = stroke_box(robot, held)
    lower, span = box[:, 0], box[:, 1] - box[:, 0]

    def run(values):
        return evaluate_starts(
            robot, segment, objective, held, values, checked, time_step, progress
        )

    result = run(lower + span * qmc.Halton(len(held), seed=1).random(samples))
    leaders = sorted(result.feasible, key=lambda s: s.peak)[:REFINED_AROUND]  # type: ignore[arg-type,return-value]
    step = 1 / samples ** (1 / len(held))  # fraction of each stroke
    directions = np.concatenate([np.eye(len(held)), -np.eye(len(held))])
    for _ in range(REFINEMENT_ROUNDS):
        if not leaders or step < FINEST_STEP:
            break
        centres = np.array([s.values for s in leaders])
        trials = centres[:, None] + step * span * directions  # (leaders, 2r, r)
        tried = run(np.clip(trials, box[:, 0], box[:, 1]).reshape(-1, len(held)))
        result = result.extended(tried)
        improved = False
        for i, leader in enumerate(leaders):
            options = [s for s in tried.samples[i * len(directions) : (i + 1) * len(directions)]]
            better = [s for s in options if s.feasible and s.peak < leader.peak]  # type: ignore[operator]
            if better:
                leaders[i] = min(better, key=lambda s: s.peak)  # type: ignore[arg-type,return-value]
                improved = True
        if not improved:
            step /= 2
    return result


def default_start(robot: Robot, segment: Segment, held: str | Sequence[str] = "x3"):
    """The documented default start: the held actuators at mid-stroke or, where the segment's
    start is out of reach there, the reachable candidate nearest mid-stroke (candidates: 101
    values per held actuator for one, 256 Halton points for several).

    Returns (values (r,), q (n,)).
    """
    held = _held(held)
    box = stroke_box(robot, held)
    if len(held) == 1:
        candidates = sweep_values(robot, held[0], 101)[:, None]
    else:
        from scipy.stats import qmc

        unit = qmc.Halton(len(held), seed=3).random(256)
        candidates = box[:, 0] + (box[:, 1] - box[:, 0]) * unit
    middle = box.mean(axis=1)
    distance = np.linalg.norm((candidates - middle) / (box[:, 1] - box[:, 0]), axis=1)
    order = np.argsort(distance, kind="stable")
    ik = inverse_kinematics(robot, segment.start, held, candidates[order])
    if not ik.reached.any():
        raise UnreachableError(
            f"{robot.name} cannot reach the start {segment.start.tolist()} of segment "
            f"{segment.name} with {', '.join(held)} anywhere in their strokes; the closest "
            f"configuration misses it by {ik.miss.min():.4g} m"
        )
    first = int(np.argmax(ik.reached))
    return candidates[order][first], ik.q[first]


def scalar_or_list(values):
    """One held actuator's value as a number, several as a list (the report's shape)."""
    values = [float(v) for v in values]
    return values[0] if len(values) == 1 else values


@dataclass(frozen=True)
class StrategyRun:
    """One motion of one strategy along one segment."""

    segment: str
    strategy: str
    start: tuple[float, ...]
    trajectory: Trajectory

    def summary(self) -> dict:
        motion = self.trajectory
        violations = motion.violations(0)
        return {
            "segment": self.segment,
            "strategy": self.strategy,
            "start_value": scalar_or_list(self.start),
            "peak_velocity_norm": float(motion.peak_velocity_norm[0]),
            "peak_kinetic": float(motion.peak_kinetic[0]),
            "within_limits": bool(motion.within_limits[0]),
            "max_tracking_error": float(motion.max_tracking_error[0]),
            "violations": [str(v) for v in violations],
        }


def fixed_start_run(
    robot: Robot,
    resolver: Resolver,
    name: str,
    segment: Segment,
    held: str | Sequence[str] = "x3",
    start: tuple[np.ndarray, np.ndarray] | None = None,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: Callable[[int], None] | None = None,
) -> StrategyRun:
    """``resolver`` along ``segment`` from a fixed start: ``start`` = (held values (r,), q (n,)),
    by default `default_start`; the run is called ``name``."""
    values, q = default_start(robot, segment, held) if start is None else start
    motion = simulate(
        robot, resolver, segment, q[None], time_step, checked=checked, progress=progress
    )
    return StrategyRun(segment.name, name, tuple(float(v) for v in values), motion)
