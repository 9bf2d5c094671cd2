"""Work cycles as a machine runs them: one continuous motion through every corner, again and
again.

A cycle is a path like any other (a `WorkCycle` is a `Chain`): the whole-cycle improved start is
`improved_start` along it (`improved_cycle_start`). `plan_cycle` puts it beside the paper's
per-segment plan, whose every corner needs a self-motion, the task point held still, from where
one segment's best motion ends to where the next one's best start begins (`Corner`). `repeat`
runs N cycles, each from where the last ended (`Repetition`: drift per cycle, the first cycle
past a limit, `Settling`); `return_map` samples the map P from the held value at the cycle's
start to the next cycle's, whose fixed points are the limit cycles (stable where |P'| < 1).

Pseudoinverse control is not repeatable on a closed path in general (Roberts & Maciejewski, IJRR
13(1), 1994): the self-motion is not integrable, so each cycle ends a little away from its
start. The drift-free strategy is the periodic global optimum (`periodic_optimum`): the bound's
transcription (`redundancy.planning.bound`) over the whole cycle with r(T) = r(0) one unknown,
each node's configuration solving y(q) = y_d(t), x_h(q) = r(t), so every cycle is the same
motion, of least peak over every periodic history of the held actuators with every checked
stroke kept at every node: its price against the free improved cycle is a measured optimum. (A
null-space return term z = −k ∇‖x − x*‖² only contracts towards a periodic motion, by a factor
per cycle set by k; closing within 1e-6 from the first cycle needs a stiff k, which raises the
peak.) A machine runs it by `HeldReference`: the held actuators follow r(t), the others resolve
the task, J_H ẋ = ẏ, in closed loop. It minimises a peak objective only, and keeps the
strokes alone: the cylinders' accelerations along a cycle, through its corners too, are
`cycle_accelerations`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property, partial
from typing import NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline

from redundancy.errors import InvalidInputError
from redundancy.model.robot import Robot, require_robot
from redundancy.model.values import is_real, is_whole
from redundancy.planning.bound import (
    GridSolution,
    Transcription,
    differentiation,
    node_times,
    resampled,
    solve_transcription,
)
from redundancy.planning.brackets import grid_over
from redundancy.planning.ik import (
    CONTINUATION_ITERATIONS,
    FOUND,
    held_names,
    named_values,
    newton,
)
from redundancy.planning.integrate import FAILED, TIME_STEP, Trajectory
from redundancy.planning.motions import Laws, per_segment, simulate_path
from redundancy.planning.refinement import Refined, checked_grids
from redundancy.planning.starts import (
    MAX_SAMPLES,
    Configurations,
    SearchResult,
    end_tolerance,
    held_actuators,
    improved_start,
)
from redundancy.planning.tasks import Chain, Segment, WorkCycle, finite_vector, jumped
from redundancy.resolution.laws import HeldRates, Resolver
from redundancy.resolution.limits import TOLERANCE as LIMIT_TOLERANCE
from redundancy.resolution.limits import Limits
from redundancy.resolution.objectives import VELOCITY, Objective
from redundancy.resolution.objectives import objective as as_objective

CYCLES = 20  # repetitions by default
STRATEGIES = ("free", "periodic")  # a repetition's law: the objective's, or drift-free
SETTLED = 1e-6  # m (or rad): a cycle whose every actuator moves less than this is closed
ROUNDING = 1e-9  # m or rad: a drift or a corner's Δ below this is the integration's rounding
MAP_SAMPLES = 25  # starts the return map samples along the reachable held stroke (`grid_over`)
GAP_SPEED = 0.1  # m/s (or rad/s): the held actuators' speed in a corner's self-motion, where
# the robot's circuit gives none
SELF_MOTION_STEPS = 50  # held values the corners' self-motions are followed through
REPEAT_TOLERANCE = 1e-7  # per adaptive step on q: the integrator's own error stays far below
# the drift measured (`SETTLED`)
HELD_GAIN = 20.0  # 1/s: feedback of the held actuators onto the periodic plan's r(t)
TASK_GAIN = 1.0  # 1/s: feedback of the task in repetitions and the return map: it keeps the
# integrator's tool error from adding up over cycles of seconds, and the motion smooth for the
# adaptive steps (at the fixed-step method's 20/s it turns stiff, for 6 × the steps)
PERIODIC_GRIDS = (48, 96)  # intervals over the whole cycle of the periodic optimum's grids
PERIODIC_MARGIN = 5e-4  # m (or rad): the periodic plan keeps the strokes this far inside at
# its nodes, so that the motion a machine runs between them keeps them too
SMOOTHNESS = 1e-4  # s²: the periodic plan's tie-break on mean r̈², beside the bound's on ṙ²
# (on the crane it halves the rms of ẍ_h and moves the peak by 2e-4 of itself)


def improved_cycle_start(
    robot: Robot,
    cycle: WorkCycle,
    objective: Objective = VELOCITY,
    held: str | Sequence[str] | None = None,
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    circuit: bool = False,
) -> SearchResult:
    """`improved_start` along the whole ``cycle``: the start of the held actuators (default
    the task's, `held_actuators`) at its first point that keeps every checked stroke through
    every segment with the least peak (or integral) of ``objective``."""
    require_robot(robot)
    held = _held(robot, cycle, held, closed=False)
    return improved_start(robot, cycle, objective, held, samples, checked, method, circuit=circuit)


def _held(robot: Robot, cycle: WorkCycle, held, closed: bool = True) -> tuple[str, ...]:
    """The held actuators' names (default the task's), once ``cycle`` is checked continuous
    (and ``closed``)."""
    cycle.check_continuous(closed)
    return held_names(robot, held_actuators(robot, cycle) if held is None else held)


def checked_cycles(cycles: object) -> int:
    """``cycles`` if it is a whole number of repetitions within [1, 10,000], else one line."""
    if not is_whole(cycles, 1, 10_000):
        raise InvalidInputError(f"cycles must be a whole number within [1, 10,000]; got {cycles!r}")
    return int(cycles)  # type: ignore[call-overload]


@dataclass(frozen=True)
class Corner:
    """A corner of the per-segment plan, at ``point`` where segment ``after`` ends and
    ``before`` starts: the plan's motion along ``after`` ends with the strokes ``end`` (n,), its
    best start of ``before`` has ``start`` (n,) (None where a segment has no feasible start),
    an actuator that its joint turns, with a stroke wider than a turn, taken the whole turns
    nearest ``end`` (`Robot.nearest_turn`: one pose).
    Between them the tool is held at the point while the held actuators move along a line from
    end to start, the fastest at ``speed`` (m/s or rad/s); ``within_limits`` whether that
    self-motion keeps every checked stroke, ``reason`` why it fails or there is no gap, ``path``
    its configurations (k, n) as far as it was followed; ``robot`` says which Δ count modulo
    a turn."""

    after: str
    before: str
    point: np.ndarray
    names: tuple[str, ...]
    held: tuple[str, ...]
    end: np.ndarray | None
    start: np.ndarray | None
    speed: float
    within_limits: bool | None = None
    reason: str | None = None
    path: np.ndarray | None = field(default=None, repr=False)
    robot: Robot | None = field(default=None, repr=False, compare=False)

    @property
    def delta(self) -> np.ndarray | None:
        """Δx = start − end of every actuator (n,), or None; of one with no stroke end that its
        joint turns, modulo its turn (`Robot.turned`)."""
        if self.start is None or self.end is None:
            return None
        change = self.start - self.end
        return change if self.robot is None else self.robot.turned(change)

    @property
    def held_delta(self) -> np.ndarray | None:
        """Δ of the held actuators (r,), or None."""
        delta = self.delta
        return None if delta is None else delta[[self.names.index(h) for h in self.held]]

    @property
    def time(self) -> float | None:
        """How long the self-motion takes with the held actuators at ``speed``, s, or None."""
        delta = self.held_delta
        return None if delta is None else float(np.abs(delta).max() / self.speed)


def gap_speed(robot: Robot, held: tuple[str, ...]) -> float:
    """The held actuators' speed in a corner's self-motion: the slowest maximum speed of the
    held cylinders in the robot's circuit, else `GAP_SPEED`."""
    circuit = robot.hydraulics
    if circuit is None:
        return GAP_SPEED
    speeds = [float(s) for name, s in zip(circuit.names, circuit.max_speeds) if name in held]
    return min(speeds, default=GAP_SPEED)


def _corner(robot, after, end, before, start, held, speed, checked) -> Corner:
    """The corner where segment ``after`` ends and ``before`` starts, between the end of the
    best motion ``end`` along one and the start of the best motion ``start`` along the other
    (None where a segment has no feasible start)."""
    names = tuple(robot.actuators.names)
    corner = partial(Corner, after.name, before.name, after.end, names, held, robot=robot)
    if end is None or start is None:
        missing = after.name if end is None else before.name
        return corner(None, None, speed, None, f"segment {missing} has no feasible start")
    end_x = end.x[0, -1]
    start_x = robot.nearest_turn(start.x[0, 0], end_x)  # a slew the short way round
    found = partial(corner, end_x, start_x, speed)
    rows = [names.index(h) for h in held]
    path = np.linspace(end_x[rows], start_x[rows], SELF_MOTION_STEPS + 1)  # a line in r-space
    q = np.empty((len(path), robot.n))
    q[0] = end.q[0, -1]
    spaces = [end.space.take(np.array([end.q.shape[1] - 1]))]  # each state, evaluated once
    for i in range(1, len(path)):  # followed step by step, so it stays on its branch
        target = np.concatenate([after.end, path[i]])[None]
        solved = newton(
            robot, q[i - 1 : i], rows, target, CONTINUATION_ITERATIONS, start=spaces[-1]
        )
        if solved.miss[0] >= FOUND:
            at = named_values(robot, held, path[i])
            return found(False, f"the self-motion loses the task point at {at}", q[:i])
        q[i] = solved.q[0]
        spaces.append(solved.space)  # type: ignore[arg-type]
    if not robot.same_pose(q[-1], start.q[0, 0], 1e-6):
        reason = "the self-motion reaches another configuration (branch)"
        return found(False, reason, q)
    x = np.concatenate([space.x for space in spaces])
    margin = Limits.strokes(robot, checked).margin(x).min()
    return found(bool(margin >= -LIMIT_TOLERANCE), None, q)


@dataclass(frozen=True, eq=False)
class CyclePlan:
    """A cycle planned two ways: ``search``, the improved start over the whole cycle, and its
    ``motion`` (None where no start keeps the strokes); and the paper's per-segment plan,
    ``segments`` (each segment's own search) with their best ``segment_motions`` and the
    ``corners`` their starts leave between them."""

    robot: Robot = field(repr=False)
    cycle: WorkCycle
    objective: Objective
    held: tuple[str, ...]
    search: SearchResult = field(repr=False)
    motion: Trajectory | None = field(repr=False)
    segments: tuple[SearchResult, ...] = field(repr=False)
    segment_motions: tuple[Trajectory | None, ...] = field(repr=False)
    corners: tuple[Corner, ...]

    @property
    def gap_time(self) -> float | None:
        """The corners' self-motions together, s (None where one has no gap)."""
        times = [c.time for c in self.corners]
        return None if any(t is None for t in times) else float(sum(times))  # type: ignore[arg-type]


def plan_cycle(
    robot: Robot,
    cycle: WorkCycle,
    objective: Objective = VELOCITY,
    held: str | Sequence[str] | None = None,
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    circuit: bool = False,
    speed: float | None = None,
    segments: Sequence[SearchResult] | None = None,
) -> CyclePlan:
    """The whole-cycle improved start and, beside it, the per-segment plan with its corners'
    self-motion gaps (the held actuators at ``speed``, default `gap_speed`). ``segments``: each
    segment's search where it was already made with these arguments (the study's), else each
    is searched here."""
    require_robot(robot)
    held = _held(robot, cycle, held, closed=False)
    speed = gap_speed(robot, held) if speed is None else speed
    if not speed > 0:
        raise InvalidInputError(f"the self-motion's speed must be > 0; got {speed}")

    def search_along(path: Segment | Chain) -> SearchResult:
        return improved_start(
            robot, path, objective, held, samples, checked, method, circuit=circuit
        )

    named = as_objective(objective).name
    if segments is not None and [(s.segment.name, s.objective.name, s.held) for s in segments] != [
        (segment.name, named, held) for segment in cycle.segments
    ]:
        raise InvalidInputError(
            f"segments must be one search of {named!r} holding {held} per segment of "
            f"{cycle.name!r}, in order"
        )
    search = search_along(cycle)
    if segments is None:
        segments = [search_along(segment) for segment in cycle.segments]
    searches = tuple(segments)
    motion, *motions = (s.best_motion if s.best is not None else None for s in (search, *searches))
    count, paths = len(searches), cycle.segments
    corners = tuple(
        _corner(robot, paths[i], motions[i], paths[j], motions[j], held, speed, checked)
        for i, j in ((i, (i + 1) % count) for i in range(count if cycle.closed else count - 1))
    )
    return CyclePlan(
        robot, cycle, objective, held, search, motion, searches, tuple(motions), corners
    )


def cycle_accelerations(cycle: WorkCycle, motion: Trajectory) -> np.ndarray:
    """ẍ (T, n) in m/s² (or rad/s²) along the first motion of ``motion``, one whole ``cycle``
    on a grid, as a machine that repeats the cycle meets it.

    Within each piece of the path it is `Trajectory.x_ddot`, which takes no difference across
    a corner: where the path turns at speed, ẏ_d jumps and so does ẋ, the path's own step. Where
    ẏ_d is continuous through a corner (it does not jump there, by the path's own rule
    `redundancy.planning.tasks.jumped`: a trapezoidal profile at rest there), and at the cycle's
    end, where the next cycle starts, when it is continuous there too, the task asks no step,
    yet a strategy may take one (the drift-free plan's held rates are solved segment by
    segment). At such a corner's sample t_c, ẍ is the mean acceleration across it, from the
    samples on either side:

        ẍ(t_c) = (ẋ(t_c + h₊) − ẋ(t_c − h₋)) / (h₊ + h₋),

    the next cycle's samples after its start being the first's (each cycle runs the same path
    from where the last ended). Smooth through the corner, it is the central difference; a step
    Δẋ there makes it at least about |Δẋ| / 2h, which no grid step h bounds."""
    t, x_dot = motion.t[0], motion.x_dot[0]
    x_ddot = motion.x_ddot[0].copy()
    segments = cycle.segments
    for k, (before, after) in enumerate(zip(segments, (*segments[1:], segments[0]))):
        if jumped(before.velocity_at(before.duration), after.velocity_at(0.0), cycle.peak):
            continue
        if k == len(segments) - 1:  # the cycle's end, the next cycle's start
            x_ddot[-1] = (x_dot[1] - x_dot[-2]) / (t[-1] + t[1] - t[0] - t[-2])
        else:
            c = int(np.argmin(np.abs(t - cycle.offsets[k + 1])))
            x_ddot[c] = (x_dot[c + 1] - x_dot[c - 1]) / (t[c + 1] - t[c - 1])
    return x_ddot


class Settling(NamedTuple):
    """Whether the held actuator's value at the cycle's start settles to a limit cycle.

    ``settled_at``: the first cycle after which every actuator moved less than `SETTLED`; else
    ``contraction``, the ratio of successive drifts of the held actuator over the last cycles
    (None with fewer than three drifts), ``limit`` the stable fixed point of the return
    map the repetition converges to and ``cycles_to_settle`` how many more cycles it needs;
    ``settles`` sums it up."""

    settles: bool
    settled_at: int | None
    contraction: float | None
    limit: float | None
    cycles_to_settle: int | None


def settling(
    values: np.ndarray, drift: np.ndarray, fixed_points: Sequence[FixedPoint] = ()
) -> Settling:
    """`Settling` from the held values at each cycle's start (N + 1,), every actuator's drift
    per cycle (N, n) and the return map's ``fixed_points`` (`ReturnMap.fixed_points`, inside
    the reachable range it samples). Closed where every drift falls below `SETTLED` for good;
    else settling only towards a stable fixed point v* (|P'| < 1) that the last cycle heads
    for, in about log(`SETTLED` / D) / log |P'| more cycles, D the last cycle's largest drift:
    near v* every drift shrinks by |P'| a cycle (the held one is (1 − P') (v − v*)), and the
    repetition closes once the largest falls below `SETTLED`. A geometric trend of the
    drifts alone is no verdict: extrapolated from a few cycles, it can point at a value no start
    reaches while longer runs wander (the contraction is reported all the same)."""
    largest = np.abs(drift).max(axis=1)
    closed = np.flatnonzero(largest <= SETTLED)
    if closed.size and np.all(largest[closed[0] :] <= SETTLED):
        return Settling(True, int(closed[0]) + 1, None, float(values[-1]), 0)
    steps = np.diff(values)
    rho = None
    if len(steps) >= 3 and np.all(steps[-3:] != 0):
        ratios = steps[-3:][1:] / steps[-3:][:-1]
        rho = float(np.median(ratios))
    heading = [
        p
        for p in fixed_points
        if p.stable and np.sign(p.value - values[-1]) == np.sign(steps[-1]) != 0
    ]
    if not heading:
        return Settling(False, None, rho, None, None)
    target = min(heading, key=lambda p: abs(p.value - values[-1]))
    slope = abs(target.slope)
    more = 1
    if slope > 0 and largest[-1] > SETTLED:
        more = math.ceil(math.log(SETTLED / largest[-1]) / math.log(slope))
    return Settling(True, None, rho, target.value, max(more, 1))


@dataclass(frozen=True, eq=False)
class Repetition:
    """N cycles run one after another from one start with one strategy (``strategy`` names
    it) by ``laws``: ``motions`` one `Trajectory` (of one) along the cycle's `Chain` per cycle,
    sampled at the adaptive steps; x (N + 1, n) the strokes and y (N + 1, m) the tool at each
    cycle's start, the last row where the last cycle ended; ``within`` (N,) whether each cycle
    kept every checked limit, and ``first_violation`` the first cycle (1-based) that passes a
    limit with the first limit it passes (its times in that cycle's time), or None."""

    robot: Robot = field(repr=False)
    cycle: WorkCycle
    strategy: str
    held: tuple[str, ...]
    laws: tuple[Resolver, ...] = field(repr=False)
    motions: tuple[Trajectory, ...] = field(repr=False)
    circuit: bool = False
    gain: float = TASK_GAIN
    tolerance: float = REPEAT_TOLERANCE

    def motion(self, number: int = 1, time_step: float = TIME_STEP) -> Trajectory:
        """Cycle ``number`` (1-based) on the grid of ``time_step``, by the dense output of the
        steps the repetition took (`Trajectory.on_grid`): not integrated again."""
        if not 1 <= number <= self.cycles:
            raise InvalidInputError(f"cycle {number} is not among 1-{self.cycles}")
        return self.motions[number - 1].on_grid(time_step)

    @property
    def cycles(self) -> int:
        return len(self.motions)

    @cached_property
    def x(self) -> np.ndarray:
        return np.array([m.x[0, 0] for m in self.motions] + [self.motions[-1].x[0, -1]])

    @cached_property
    def y(self) -> np.ndarray:
        return np.array([m.y[0, 0] for m in self.motions] + [self.motions[-1].y[0, -1]])

    @cached_property
    def within(self) -> np.ndarray:
        return np.array([bool(m.within_limits[0]) for m in self.motions])

    @cached_property
    def first_violation(self) -> tuple[int, str] | None:
        for number, motion in enumerate(self.motions, start=1):
            found = motion.violations(0)
            if found:
                return number, str(found[0])
            if not motion.within_limits[0]:
                return number, f"the motion failed {FAILED}"
        return None

    @property
    def drift(self) -> np.ndarray:
        """Each actuator's drift per cycle (N, n): stroke at its end − at its start, m or rad;
        of one with no stroke end that its joint turns, modulo its turn (`Robot.turned`): a
        cycle that turns it once around (a slew following a circle) leaves the machine as it
        found it."""
        return self.robot.turned(np.diff(self.x, axis=0))

    @property
    def tool_drift(self) -> np.ndarray:
        """|y(end) − y(start)| of the tool per cycle (N,), m (and rad)."""
        return np.linalg.norm(np.diff(self.y, axis=0), axis=1)

    @property
    def held_values(self) -> np.ndarray:
        """The held actuators at each cycle's start (N + 1, r)."""
        return self.x[:, self.robot.actuators.rows(self.held)]

    @property
    def settling(self) -> Settling:
        """Whether the repetition closed; without the return map's fixed points nothing else
        counts as settling (`settling_with`)."""
        return self.settling_with(())

    def settling_with(self, fixed_points: Sequence[FixedPoint]) -> Settling:
        """Whether the repetition closes or converges to one of the return map's stable
        ``fixed_points`` (`settling`)."""
        return settling(self.held_values[:, 0], self.drift, fixed_points)

    def score(self, objective: Objective) -> float:
        """The first cycle's ``objective``."""
        return float(self.motions[0].score(objective)[0])


def repeat(
    robot: Robot,
    cycle: WorkCycle,
    laws: Laws,
    start: np.ndarray,
    cycles: int = CYCLES,
    strategy: str = "free",
    held: str | Sequence[str] | None = None,
    checked: tuple[str, ...] | None = None,
    circuit: bool = False,
    objective: Objective | None = None,
    tolerance: float = REPEAT_TOLERANCE,
    gain: float = TASK_GAIN,
) -> Repetition:
    """Run ``cycles`` cycles with ``laws`` (one `Resolver`, or one per segment) from the
    configuration ``start`` (n,), each from where the last ended, with closed-loop tracking of
    the task (gain K, 1/s), adaptively to ``tolerance`` and sampled at the steps
    (`Repetition.motion` gives a cycle on the grid)."""
    require_robot(robot)
    if strategy not in STRATEGIES:
        raise InvalidInputError(
            f"unknown strategy {strategy!r}; strategies: {', '.join(STRATEGIES)}"
        )
    held = _held(robot, cycle, held)
    cycles = checked_cycles(cycles)
    q = robot.configuration(start, "start")
    if len(q) != 1:
        raise InvalidInputError(
            f"start must be one configuration ({robot.n},): repetitions run one after another; "
            f"got shape {np.shape(start)}"
        )
    run = partial(simulate_path, robot, laws, cycle, checked=checked, sparse=True)
    motions = []
    for _ in range(cycles):
        motions.append(run(q, objective=objective, circuit=circuit, gain=gain, tolerance=tolerance))
        q = motions[-1].q[:, -1]
    laws = per_segment(cycle, laws)
    return Repetition(robot, cycle, strategy, held, laws, tuple(motions), circuit, gain, tolerance)


@dataclass(frozen=True)
class ReturnMap:
    """The map P from the held actuator's value at the cycle's start to its value there one
    cycle later, sampled at ``values`` (k,): ``following`` (k,) (NaN where the start is out of
    reach or the motion failed), ``within`` (k,) whether that cycle kept the strokes; its
    ``fixed_points``: the limit cycles."""

    held: str
    values: np.ndarray
    following: np.ndarray
    within: np.ndarray

    @property
    def fixed_points(self) -> list[FixedPoint]:
        """Where P(v) − v changes sign between two samples, one of them moved by more than
        `SETTLED` (the drift a repetition counts as none: a map within that of the identity, as
        a cycle that retraces its path has, changes sign by integration error alone): v* and
        P'(v*) of the parabola through those two samples and the next one nearer v*, else of
        the secant (a secant alone gave one side's slope where v* fell on a sample, whichever
        side rounding put P(v*) − v* on: 0.173 or 0.185 where the map contracts by 0.178, and
        put the crane's limit cycle 4e-5 m off between samples 12 mm apart)."""
        v, p = self.values, self.following
        g = p - v
        a, b = g[:-1], g[1:]
        crossed = np.isfinite(a) & np.isfinite(b) & (a * b <= 0) & (a != b)
        i = np.flatnonzero(crossed & (np.maximum(np.abs(a), np.abs(b)) > SETTLED))
        kept = self.within[i] & self.within[i + 1]
        found = [self._fixed_point(int(k)) for k in i]
        return [FixedPoint(r, s, bool(k)) for (r, s), k in zip(found, kept)]

    @property
    def identity(self) -> bool:
        """Whether every start it reached comes back within `SETTLED` of itself: P(v) = v to
        the accuracy at which a repetition counts as closed."""
        drift = np.abs(self.following - self.values)
        drift = drift[np.isfinite(drift)]
        return bool(drift.size) and bool(np.all(drift <= SETTLED))

    def _fixed_point(self, i: int) -> tuple[float, float]:
        """v* in [v_i, v_i+1] and P'(v*) (see `fixed_points`)."""
        v, p = self.values, self.following
        g = p - v
        root = v[i] - g[i] * (v[i + 1] - v[i]) / (g[i + 1] - g[i])  # the secant's
        third = i - 1 if root - v[i] < v[i + 1] - root else i + 2
        if not (0 <= third < len(v) and np.isfinite(p[third])):
            return float(root), float((p[i + 1] - p[i]) / (v[i + 1] - v[i]))
        rows = [i, i + 1, third]
        curvature, linear, constant = np.polyfit(v[rows], p[rows], 2)
        roots = np.roots([curvature, linear - 1, constant])  # P(v) = v on the parabola
        low, high = sorted((v[i], v[i + 1]))  # values in any order
        inside = [r.real for r in roots if r.imag == 0 and low <= r.real <= high]
        if inside:
            root = min(inside, key=lambda r: abs(r - root))
        return float(root), float(2 * curvature * root + linear)


class FixedPoint(NamedTuple):
    """A limit cycle: the held ``value`` v* with P(v*) = v*, the ``slope`` P'(v*) (stable where
    |P'| < 1), and whether both samples around it keep the strokes."""

    value: float
    slope: float
    keeps_the_strokes: bool

    @property
    def stable(self) -> bool:
        return abs(self.slope) < 1


def return_map(
    robot: Robot,
    cycle: WorkCycle,
    laws: Laws,
    held: str | Sequence[str] | None = None,
    values: np.ndarray | None = None,
    checked: tuple[str, ...] | None = None,
    count: int = MAP_SAMPLES,
    near: np.ndarray | None = None,
) -> ReturnMap:
    """P sampled at ``values`` of the held actuator (default ``count`` evenly along the pieces
    of its stroke over which the cycle's start is reachable, with every piece's ends, one
    inside a narrower piece they step over and one in every gap: `grid_over`), all integrated
    as one batch. Its starts lie on the assembly branch of ``near``, a configuration (n,) at
    the cycle's start (a repetition's last one: the branch it runs on, where its first cycle
    changed branch), by default on the side of the fold of the configuration inverse
    kinematics picks at mid-stroke (the first of `Configurations.branches`)."""
    require_robot(robot)
    found = _held(robot, cycle, held)
    if len(found) != 1:
        raise InvalidInputError(
            f"it maps one held actuator's value to the next cycle's; {robot.name} on "
            f"{cycle.name!r} holds {len(found)} ({', '.join(found)}): the repetition's drift "
            "tells instead"
        )
    name = found[0]
    configurations = (
        Configurations.branches(robot, cycle, name)[0]
        if near is None
        else Configurations.near(robot, cycle, name, near)
    )
    if values is None:
        if not is_whole(count, 2, MAX_SAMPLES):
            raise InvalidInputError(
                f"count must be a whole number within [2, {MAX_SAMPLES:,}]; got {count!r}"
            )
        values = grid_over(configurations.reachable(end_tolerance(robot, name, None)), count)
    given, values = values, finite_vector(values)
    if values is None:
        raise InvalidInputError(
            f"values must be finite strokes of {name}, one per sample, shape (k,); got {given!r}"
        )
    starts = configurations.at(values)
    ok = starts.reachable
    following = np.full(len(values), np.nan)
    within = np.zeros(len(values), dtype=bool)
    if ok.any():
        motions = simulate_path(
            robot, laws, cycle, starts.q[ok], checked=checked, sparse=True, gain=TASK_GAIN
        )
        end = motions.x[:, -1, robot.actuators.rows(name)[0]]
        following[ok] = np.where(motions.failed, np.nan, end)
        within[ok] = motions.within_limits
    return ReturnMap(name, values, following, within)


class HeldReference(HeldRates):
    """Runs a periodic plan: the held actuators follow the plan's r(t) along one segment (t in
    s from the segment's start), ẋ_h = ṙ(t) + k (r(t) − x_h), and the others resolve the task,
    J_H ẋ = ẏ (`HeldRates`: the one ẋ solving [J_H; E_h] ẋ = [ẏ; ẋ_h], r = n − m held).
    r(t) is the cubic spline through the plan's nodes, (N,) or (N, r) (twice differentiable, so
    the integrator steps over the nodes; ``periodic`` where one segment is the whole cycle)."""

    name = "periodic plan (held actuators follow r(t))"

    def __init__(
        self,
        rows: int | Sequence[int],
        t: np.ndarray,
        r: np.ndarray,
        gain: float = HELD_GAIN,
        periodic=False,
    ):
        super().__init__(rows)
        self.gain = gain
        r = np.reshape(r, (len(t), len(self.rows)))
        self.reference = CubicSpline(t, r, bc_type="periodic" if periodic else "not-a-knot")
        self.rate = self.reference.derivative()

    def __repr__(self) -> str:
        return f"HeldReference(rows={self.rows}, gain={self.gain})"

    def held_velocity(self, t: np.ndarray, x_h: np.ndarray) -> np.ndarray:
        """ẋ_h = ṙ(t) + k (r(t) − x_h), (k, h)."""
        return self.rate(t) + self.gain * (self.reference(t) - x_h)


@dataclass(frozen=True, eq=False)
class PeriodicOptimum(Refined):
    """The drift-free strategy (module docstring): the motion of least peak of ``objective``
    over every periodic history of the held actuators over the whole cycle, on each of its
    ``grids``. At the finest grid's nodes: cycle times t (N,), each node's ``piece`` (segment),
    its segment time ``local``, q (N, n), the held strokes r and rates ṙ ((N,) with one held
    actuator, (N, r) with several, as ``held`` is its name or their names), the objective's
    ``measure`` (N,)."""

    robot: Robot = field(repr=False)
    cycle: WorkCycle
    objective: Objective
    held: str | tuple[str, ...]
    t: np.ndarray
    piece: np.ndarray
    local: np.ndarray
    q: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    measure: np.ndarray
    grids: tuple[GridSolution, ...]

    @property
    def peak(self) -> float:
        """The plan's peak of ``objective``: the optimum on the finest grid."""
        return self.optimum

    @property
    def start(self) -> np.ndarray:
        """The configuration at the cycle's start (n,)."""
        return self.q[0]

    def laws(self, gain: float = HELD_GAIN) -> tuple[HeldReference, ...]:
        """One `HeldReference` per segment: the law a machine runs the plan by."""
        row, single = self.robot.actuators.rows(self.held), len(self.cycle.segments) == 1
        return tuple(
            HeldReference(row, self.local[self.piece == i], self.r[self.piece == i], gain, single)
            for i in range(len(self.cycle.segments))
        )


def periodic_optimum(
    robot: Robot,
    cycle: WorkCycle,
    guess: Trajectory,
    objective: Objective = VELOCITY,
    held: str | Sequence[str] | None = None,
    checked: tuple[str, ...] | None = None,
    grids: tuple[int, ...] = PERIODIC_GRIDS,
    margin: float = PERIODIC_MARGIN,
    smoothness: float = SMOOTHNESS,
) -> PeriodicOptimum:
    """The periodic global optimum over the whole cycle (module docstring), from the first
    motion of ``guess`` (e.g. the free improved cycle) with its drift taken out linearly in
    time; ``grids`` are interval counts over the whole cycle, each solved from the last.
    ``held`` names the held actuators (default the task's), one or several."""
    require_robot(robot)
    names = _held(robot, cycle, held)
    if objective.reduction != "peak":
        raise InvalidInputError(
            f"the periodic optimum minimises a peak; objective {objective.name!r} reduces its "
            f"measure by {objective.reduction!r}"
        )
    grids = checked_grids(grids, 2)
    actuators = [robot.actuators[name] for name in names]
    largest = min(a.upper - a.lower for a in actuators) / 4
    bounds = (("margin", margin, largest, actuators[0].unit), ("smoothness", smoothness, 1.0, "s²"))
    for key, value, most, unit in bounds:
        if not (is_real(value) and 0 <= value <= most):
            raise InvalidInputError(f"{key} must be within [0, {most:g}] {unit}; got {value!r}")
    rows = robot.actuators.rows(names)
    limits = Limits.strokes(robot, checked)
    others = Limits.strokes(robot, [n for n in limits.names if n not in names])
    box = [
        (a.lower + margin, a.upper - margin) if a.name in limits.names else (None, None)
        for a in actuators
    ]
    period, solutions = cycle.duration, []
    t0, r0 = guess.t[0], guess.x[0][:, rows]
    nodes_t, nodes_q = t0, guess.q[0]  # where the next grid's configurations are interpolated from
    # and its held strokes (periodic in the cycle's time): the free motion's, its drift out
    unknown_t, unknown_r = t0, r0 - (r0[-1] - r0[0]) * t0[:, None] / period
    for intervals in grids:
        q = resampled(node_times(cycle, intervals), nodes_t, nodes_q)
        problem = Transcription(
            robot,
            objective,
            cycle,
            rows,
            others,
            intervals,
            q,
            periodic=True,
            margin=margin,
            smoothness=smoothness,
            differences=differentiation,
        )
        r = resampled(problem.unknown_times(), unknown_t, unknown_r)
        try:
            r, grid, nodes = solve_transcription(problem, r, box, intervals)
        except InvalidInputError as error:
            raise InvalidInputError(f"the periodic optimum found no motion: {error}") from None
        solutions.append(grid)
        nodes_t, nodes_q = problem.t, nodes.space.q
        order = np.argsort(problem.unknown_times())
        unknown_t = np.append(problem.unknown_times()[order], period)
        unknown_r = np.concatenate([r[order], r[:1]])
    # the peak is taken at the nodes with central differences, blind to a held history that
    # alternates node by node; the plan a machine runs is that history with the alternation
    # filtered out ((1, 2, 1) / 4 inside each segment; the corners, where the held rate may
    # jump, kept), its configurations solved afresh from the solution's (the last states that
    # reached every node may be an earlier iterate's, too far for a continuation's few steps)
    smooth = (np.roll(r, 1, axis=0) + 2 * r + np.roll(r, -1, axis=0)) / 4
    corners = problem.owner[np.flatnonzero(np.diff(problem.piece, prepend=-1))]
    smooth[corners] = r[corners]
    r_nodes = smooth[problem.owner]
    r_dot = problem.D @ smooth
    q = problem.configurations(smooth, nodes.space)
    one = len(names) == 1
    return PeriodicOptimum(
        robot,
        cycle,
        objective,
        names[0] if one else names,
        problem.t,
        problem.piece,
        problem.local,
        q.copy(),
        r_nodes[:, 0] if one else r_nodes,
        r_dot[:, 0] if one else r_dot,
        nodes.measure,
        tuple(solutions),
    )
