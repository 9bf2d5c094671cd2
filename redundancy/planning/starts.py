"""Choosing the start of a motion: the default start, or the paper's improved initial
configuration.

The improved method (section 2, steps i-v): sample the held actuators (the crane's x3init) over
their strokes; for each sample find the initial configuration by inverse kinematics, integrate
the objective's law along the path (a segment, or a work cycle's `Chain`, searched as one), keep
the samples whose motion stays inside the actuator limits the whole way, and return the one
with the lowest peak (or integral) of the objective. Every sample, whichever search asks for it,
is evaluated by `evaluate_starts`: feasible where its margin is ≥ −`TOLERANCE`
(`redundancy.resolution.limits`). With one held actuator, each side of the fold (det [J; A_h]
of one sign: an arm's elbow up, elbow down) on which inverse kinematics reaches the path's start
inside the joint ranges, at `SEEDED` held values over the stroke or with the held actuator
free, is searched on its own, its starts continued along the held value from the nearest of
those configurations and kept on its side, and the best start is the best of them all
(`Configurations.branches`). With several held actuators, a held value has the one start
configuration inverse kinematics reaches from its seeds. Methods:

- "fast" (r = 1, the default): the margin μ(v) of a start v, the least distance of a checked
  stroke to its limits over the motion and of the start to its joint limits, is continuous in
  v, so the ends of the feasible set are its zeros. The reachable starts are located first by
  continuation along v (no integration), pieces of them cut off from the rest too (a piece at
  the end of the branch, narrower than the scan's spacing, by dividing the interval beside that
  end); `GRID` of them are integrated, evenly along the pieces with every piece's ends (one
  inside each piece they step over, one in each gap), and each round
  integrates the probes of every bracket of the feasible set (`redundancy.planning.brackets`)
  and of the least peak (beside it too where it lies at an end of the feasible set), until
  every end is located to ``tolerance``. Where none of the grid's starts is feasible, a
  feasible set narrower than its spacing may lie between them: rounds first halve the
  interval around the highest margin (the grid's motions run to their end where every one
  stopped early), until a start is feasible, that summit is located to ``tolerance``, or it is
  too far below 0 to rise to it between the samples
  (`redundancy.planning.brackets.summit_probes`).
- "sweep": the paper's uniform sweep of ``samples`` values (r = 1); for r > 1, ``samples``
  scrambled Halton points over the stroke box (a grid would cost samples^r), the best feasible
  ones then refined by compass search: each round tries every leader ± h along each direction
  of an orthonormal basis that turns from round to round (`_poll_bases`; the first is the held
  actuators' own axes), one batch, moves a leader to its best feasible improvement, and halves
  h when none improved, from h = stroke / samples^(1/r) down to stroke / 1000; a round whose
  trials are all out of reach is recorded as unreachable samples. That refinement is local:
  where the peak has several basins over the box, the best start found may lie in the wrong
  one; more ``samples`` sample the box more finely. Where no Halton point reaches the path's
  start (the held values that do can be a small part of the box where r is large), the sweep
  begins from the held values of configurations that reach it with every actuator free
  (`free_held_values`).

Each round's samples are integrated as one batch, adaptively and sampled sparsely
(`redundancy.planning.integrate`); they rank the starts. The best start's figure,
`SearchResult.best_peak`, is taken over its motion on the grid (`SearchResult.motion`): a peak
can fall between sparse samples (1 % above them on the slewing crane's lift-swing). A dynamic
objective (a pump energy), whose figure at sparse samples misranks starts by a few per cent, has
its feasible samples of least figure ranked again on the grid (`SearchResult.best`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, fields, replace
from functools import cached_property, partial, reduce
from typing import cast

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError, placed
from redundancy.model.robot import Robot, require_robot
from redundancy.model.values import is_finite, is_whole
from redundancy.planning.brackets import (
    bracket_probes,
    edge_probes,
    end_probe,
    grid_over,
    new_probes,
    summit_probes,
    vertex_probes,
)
from redundancy.planning.ik import (
    FOUND,
    continue_held,
    every_configuration,
    fold_side,
    free_configurations,
    held_indices,
    held_names,
    inverse_kinematics,
    require_redundancy,
)
from redundancy.planning.integrate import (
    FAILED,
    REPORT_TOLERANCE,
    TIME_STEP,
    TOLERANCE,
    Trajectory,
    concatenated,
)
from redundancy.planning.motions import simulate_path
from redundancy.planning.tasks import Chain, Segment, checked_path
from redundancy.resolution.limits import TOLERANCE as LIMIT_TOLERANCE
from redundancy.resolution.limits import Limits, Violation, amount
from redundancy.resolution.objectives import Objective, objectives_of
from redundancy.resolution.objectives import objective as as_objective
from redundancy.resolution.state import evaluate

METHODS = ("fast", "sweep")
MAX_SAMPLES = 10_000  # starts of one sweep, integrated as one batch: about 47 MB per 1,000
GRID = 12  # starts of the fast search's first round along the reachable pieces (`grid_over`)
REACH_GRID = 24  # starts whose reachability the fast search checks first, over the stroke
ANCHOR_SEEDS = 8  # Newton's seeds per value where the branches' configurations are sought
SEEDED = 9  # held values, over the stroke, where they are sought (mid-stroke among them)
END_TOLERANCE = 5e-4  # of the held stroke: the fast search locates the feasible ends to this,
# half the spacing of a 1,000-sample sweep
ROUNDS = 8  # refinement rounds of the fast search, at most, per phase
REFINED_AROUND = 3  # best feasible samples the compass search refines (r > 1)
REFINEMENT_ROUNDS = 30  # at most, each one batch of REFINED_AROUND · 2r simulations
TIE = 1e-6  # relative: the best peaks of two branches this close are one (`_best_branch`)
RANKED = 24  # feasible samples of least estimate a dynamic objective ranks again on the grid
FINEST_STEP = 1e-3  # compass step at which refinement stops, as a fraction of each stroke


@dataclass(frozen=True)
class Sample:
    """One start of a search: the held actuators' ``values`` (m or rad), the objective's
    ``peak`` (its peak or integral; None if the start was unreachable), whether every checked
    limit held, the ``margin`` μ (m or rad; −inf where unknown), its violations and why it is
    not feasible."""

    values: tuple[float, ...]
    peak: float | None
    feasible: bool
    margin: float = -np.inf
    violations: tuple[Violation, ...] = ()
    reason: str | None = None

    @property
    def value(self) -> float:
        """The held value, for one held actuator."""
        if len(self.values) != 1:
            raise InvalidInputError(f"this sample holds {len(self.values)} actuators; use values")
        return self.values[0]


@dataclass(frozen=True)
class SearchResult:
    """Every sample of a search of the start along one path (a segment, or a work cycle's
    `Chain`), and the motions of the reachable ones.

    ``batches`` holds the motions of each batch the search integrated, in order, one per
    reachable sample (sparse samples); ``rows[i]`` is sample i's motion among them all, counted
    across the batches (−1 when unreachable). ``method`` is the search that chose the samples.
    """

    robot: Robot = field(repr=False)
    segment: Segment | Chain
    objective: Objective
    held: tuple[str, ...]
    samples: tuple[Sample, ...]
    batches: tuple[Trajectory, ...] = field(repr=False)
    rows: np.ndarray
    method: str = "sweep"

    @property
    def rounds(self) -> int:
        """How many batches the search integrated."""
        return len(self.batches)

    @cached_property
    def trajectory(self) -> Trajectory:
        """Every reachable sample's motion, as one batch: row ``rows[i]`` is sample i's. Joined
        when first read, not per round: a search reads its batches' starts alone."""
        return reduce(concatenated, self.batches)

    def start_configuration(self, sample: Sample) -> np.ndarray:
        """The configuration (n,) the motion from a reachable ``sample`` starts at."""
        if sample not in self.samples:
            raise InvalidInputError(f"{sample} is not a sample of this search")
        row = int(self.rows[self.samples.index(sample)])
        if row < 0:
            raise InvalidInputError(f"the start {sample.values} of {self.held} is unreachable")
        ends = np.cumsum([len(batch) for batch in self.batches])  # each batch's last row + 1
        i = int(np.searchsorted(ends, row, side="right"))
        return self.batches[i].q[row - ends[i] + len(self.batches[i]), 0]

    @property
    def values(self) -> np.ndarray:
        """The samples' held values, (k, r)."""
        return np.array([s.values for s in self.samples])

    @property
    def simulations(self) -> int:
        """How many motions the search integrated."""
        return int(np.count_nonzero(self.rows >= 0))

    @property
    def feasible(self) -> list[Sample]:
        """The feasible samples, in order of their held values."""
        return sorted((s for s in self.samples if s.feasible), key=lambda s: s.values)

    @property
    def feasible_box(self) -> np.ndarray | None:
        """Per held actuator, the smallest and largest feasible sampled value (r, 2), or None."""
        feasible = np.array([s.values for s in self.feasible])
        return np.stack([feasible.min(0), feasible.max(0)], axis=1) if feasible.size else None

    @property
    def feasible_range(self) -> tuple[float, float] | None:
        """The smallest and largest feasible sampled value of one held actuator, or None."""
        box = self.feasible_box
        if box is None:
            return None
        if len(box) != 1:
            raise InvalidInputError(
                f"this search holds {len(box)} actuators ({', '.join(self.held)}); use feasible_box"
            )
        return float(box[0, 0]), float(box[0, 1])

    @cached_property
    def best(self) -> Sample | None:
        """The feasible sample with the lowest objective (step v), or None. A dynamic
        objective's figure at sparse samples reads ẍ from differences of ẋ between the steps,
        and misranks starts by a few per cent (4 % on the excavator's LS energy along 3-1): its
        `RANKED` feasible samples of least figure are ranked again by their motions on the
        grid, as `best_peak` is taken."""
        ranked = sorted(self.feasible, key=lambda s: s.peak)  # type: ignore[arg-type,return-value]
        if len(ranked) < 2 or not self.objective.dynamic:
            return ranked[0] if ranked else None
        ranked = ranked[:RANKED]
        starts = np.array([self.start_configuration(sample) for sample in ranked])
        motions = self._on_grid(starts)
        scores = np.where(motions.within_limits, motions.score(self.objective), np.inf)
        scores[np.isnan(scores)] = np.inf
        return ranked[int(np.argmin(scores))] if np.isfinite(scores).any() else ranked[0]

    @cached_property
    def best_motion(self) -> Trajectory:
        """The best start's motion on the `TIME_STEP` grid (``motion()``), sampled once."""
        return self.motion()

    @property
    def best_peak(self) -> float | None:
        """The objective (peak or integral) over `best_motion`, or None without a best start:
        the best start's figure, where ``best.peak`` is the search's estimate at its samples."""
        if self.best is None:
            return None
        return float(self.best_motion.score(self.objective)[0])

    @property
    def closest_violation(self) -> Violation | None:
        """When nothing is feasible: the smallest worst-excess among the reachable samples."""
        worst = [max(s.violations, key=lambda v: v.excess) for s in self.samples if s.violations]
        return min(worst, key=lambda v: v.excess) if worst else None

    def motion(self, sample: Sample | None = None, time_step: float = TIME_STEP) -> Trajectory:
        """The motion from ``sample`` (default the best) on the grid of ``time_step``: a
        trajectory of one, integrated from its start along the path (segment by segment for a
        chain) at `REPORT_TOLERANCE`, which keeps the power balance on the grid (the search's
        steps, at its looser tolerance, do not)."""
        sample = self.best if sample is None else sample
        if sample is None:
            raise InvalidInputError(
                f"no start on {self.segment.label} keeps every checked limit for the "
                f"{self.objective.name} objective; closest: {self.closest_violation}"
            )
        return self._on_grid(self.start_configuration(sample)[None], time_step)

    def _on_grid(self, starts: np.ndarray, time_step: float = TIME_STEP) -> Trajectory:
        """The motions from ``starts`` (k, n) on the grid of ``time_step``, at
        `REPORT_TOLERANCE`, checked as the search's were."""
        searched = self.batches[0]
        return simulate_path(
            self.robot,
            self.objective.resolver,
            self.segment,
            starts,
            time_step,
            checked=searched.checked,
            tolerance=REPORT_TOLERANCE,
            objective=self.objective,
            circuit=searched.circuit,
        )

    def extended(self, other: SearchResult) -> SearchResult:
        """This search with the samples of ``other`` (same path and objective) appended."""
        offset = sum(len(batch) for batch in self.batches)
        rows = np.concatenate([self.rows, np.where(other.rows < 0, -1, other.rows + offset)])
        return replace(
            self,
            samples=self.samples + other.samples,
            batches=self.batches + other.batches,
            rows=rows,
        )


def held_actuators(robot: Robot, path: Segment | Chain) -> tuple[str, ...]:
    """The actuators a search holds on ``path`` where none are named: its task's ``held`` (a
    work cycle's, or that of the task a segment or chain was read from), or the last n − m."""
    require_redundancy(robot)
    pieces = path.segments if isinstance(path, Chain) else (path,)
    told = getattr(path, "held", ()) or next((s.held for s in pieces if s.held), ())
    return told or tuple(robot.actuators.names[robot.m :])


def chosen_held(robot: Robot, path: Segment | Chain, held) -> tuple[str, ...]:
    """The held actuators' names: ``held`` (one name, or several), or by default
    `held_actuators` on ``path``."""
    return held_names(robot, held_actuators(robot, path) if held is None else held)


def stroke_box(robot: Robot, held: tuple[str, ...]) -> np.ndarray:
    """The held actuators' strokes (r, 2), checked finite."""
    held_indices(robot, held)
    box = np.array([[robot.actuators[h].lower, robot.actuators[h].upper] for h in held])
    if not np.all(np.isfinite(box)):
        raise InvalidInputError(f"held actuators {list(held)} need finite strokes to sample")
    return box


def _unreachable(robot: Robot, path, how: str, miss: float | None = None) -> UnreachableError:
    """The error saying ``robot`` cannot reach the start of ``path`` ``how`` (and by how much
    the closest configuration ``miss``es it, m)."""
    closest = (
        "" if miss is None else f"; the closest configuration misses it by {amount(miss, 'm')}"
    )
    return UnreachableError(
        placed(
            getattr(path, "source", ""),  # a segment's or a work cycle's task file
            f"{robot.name} cannot reach the start {path.start.tolist()} of {path.label} "
            f"{how}{closest}",
        )
    )


def sweep_values(robot: Robot, held: str, samples: int) -> np.ndarray:
    """``samples`` values evenly over one held actuator's stroke (step iii), (samples,)."""
    if samples < 1:
        raise InvalidInputError(f"samples must be at least 1; got {samples}")
    lower, upper = stroke_box(robot, (held,))[0]
    if samples == 1:
        return np.array([(lower + upper) / 2])
    return np.linspace(lower, upper, samples)


@dataclass(frozen=True)
class Starts:
    """Start configurations of a segment at held values: values (k, r), q (k, n), and the
    joint margins (k,) of q (−inf where no configuration reaches the point); ``miss`` (k,) m,
    how far the closest configuration inside the joint limits misses the point (0 where
    reached)."""

    values: np.ndarray
    q: np.ndarray
    joint_margins: np.ndarray
    miss: np.ndarray

    @property
    def reachable(self) -> np.ndarray:
        return self.joint_margins >= -LIMIT_TOLERANCE

    def merged(self, other: Starts) -> Starts:
        """These starts and ``other`` in order of their held value."""
        both = [
            np.concatenate([getattr(self, f.name), getattr(other, f.name)]) for f in fields(self)
        ]
        order = np.argsort(both[0][:, 0], kind="stable")
        return Starts(*(values[order] for values in both))

    def sample(self, i: int) -> Sample:
        """Start i as the sample of a search, where it is unreachable."""
        values = tuple(float(v) for v in self.values[i])
        return Sample(values, None, False, self.joint_margins[i], (), self.reason(i))

    def reason(self, i: int) -> str:
        """Why start i is unreachable."""
        if self.miss[i] > 0:
            return f"start unreachable (misses by {amount(self.miss[i], 'm')})"
        if not np.isfinite(self.joint_margins[i]):
            return "start unreachable (no configuration on this branch reaches it)"
        outside = -self.joint_margins[i]
        return f"start unreachable inside the joint limits (outside them by {outside:.3g})"


class Configurations:
    """Start configurations at the point of a segment for one held actuator on one assembly
    branch, by continuation from those found so far (``known``: held values (j,), their
    configurations (j, n) and ``sides`` of the fold (j,), found where not given): `branches`
    seeds one per branch, `near` one on a given branch."""

    def __init__(
        self,
        robot: Robot,
        segment: Segment | Chain,
        held: str,
        known: tuple[np.ndarray, np.ndarray],
        sides: np.ndarray | None = None,
    ):
        self.robot, self.point, self.held, self.segment = robot, segment.start, held, segment
        self._reach: dict[float, np.ndarray] = {}
        self.row = held_indices(robot, [held])[0]
        self.joints = Limits.joints(robot)
        self.scan = sweep_values(robot, held, REACH_GRID)
        if sides is None:
            sides = fold_side(evaluate(robot, known[1]), [self.row])
        self.known = (*known, sides)

    @classmethod
    def branches(cls, robot: Robot, segment: Segment | Chain, held: str) -> list[Configurations]:
        """One per side of the fold (`fold_side`: an arm's elbow up, elbow down) on which the
        segment's start is reached inside the joint ranges, seeded by every configuration on
        that side that Newton from `ANCHOR_SEEDS` seeds finds at `SEEDED` held values over
        the stroke or with the held actuator free: a start is continued from the nearest of
        them on its side, so that a piece of a branch cut off from the others along the held
        value (by the joint ranges, or by the end of a slew's stroke where the slew turns on) is
        searched too, as far as a scanned value lands on it. The first is the side of the
        configuration `inverse_kinematics` picks nearest mid-stroke."""
        scan, point = sweep_values(robot, held, SEEDED), segment.start
        middle_first = scan[np.argsort(np.abs(scan - scan.mean()), kind="stable")]
        found, at, found_sides = every_configuration(
            robot, point, [held], middle_first, ANCHOR_SEEDS
        )
        free, miss = free_configurations(robot, point, ANCHOR_SEEDS)  # the held actuator free
        seeds = np.concatenate([found, free])
        if not len(seeds):
            how = f"with {held} anywhere in its stroke inside its joint limits"
            raise _unreachable(robot, segment, how, miss)
        row = held_indices(robot, [held])[0]
        space = evaluate(robot, free)  # where the held actuator was free: its value and side
        values = np.concatenate([at[:, 0], space.x[:, row]])
        sides = np.concatenate([found_sides, fold_side(space, [row])])
        return [
            cls(
                robot,
                segment,
                held,
                (values[sides == side], seeds[sides == side]),
                sides[sides == side],
            )
            for side in dict.fromkeys(sides)  # in the order of the seeds
        ]

    @classmethod
    def near(
        cls, robot: Robot, segment: Segment | Chain, held: str, q: np.ndarray
    ) -> Configurations:
        """On the branch of ``q`` (n,), a configuration at the segment's start."""
        q = robot.configuration(q, "near")[:1]
        return cls(
            robot, segment, held, (evaluate(robot, q).x[:, held_indices(robot, [held])[0]], q)
        )

    def reachable(self, tolerance: float) -> np.ndarray:
        """The pieces (p, 2) of the held stroke over which the start is reachable, in order,
        from `REACH_GRID` starts over the stroke with the ends of the reachable ones located to
        ``tolerance`` by bisection of the joint margin, and the end of the branch located where
        a start beside it lies outside the joint limits (`edge_probes`: a piece inside them,
        narrower than the scan's spacing, may lie at that end): no integration, so one scan
        serves every objective's search (kept per tolerance)."""
        if tolerance not in self._reach:
            reach = self.at(self.scan)
            for _ in range(ROUNDS):
                values, margins = reach.values[:, 0], reach.joint_margins
                probes = new_probes(
                    bracket_probes(values, margins, reach.reachable, tolerance)
                    + edge_probes(values, margins, tolerance),
                    values,
                    tolerance,
                )
                if not probes.size:
                    break
                reach = reach.merged(self.at(probes))
            ends = np.flatnonzero(np.diff(np.concatenate([[0], reach.reachable, [0]])))
            self._reach[tolerance] = reach.values[np.stack([ends[::2], ends[1::2] - 1], 1), 0]
        if not self._reach[tolerance].size:
            how = f"inside its joint limits with {self.held} anywhere in its stroke"
            raise _unreachable(self.robot, self.segment, how)
        return self._reach[tolerance]

    def at(self, values: np.ndarray) -> Starts:
        """Starts at held ``values`` (k,)."""
        q, residual, sides = continue_held(self.robot, self.point, self.row, self.known, values)
        found = residual < FOUND
        margins = np.where(found, self.joints.margin(q), -np.inf)
        inside = found & (margins >= -LIMIT_TOLERANCE)
        known_values, known_q, known_sides = self.known
        self.known = (
            np.concatenate([known_values, values[inside]]),
            np.concatenate([known_q, q[inside]]),
            np.concatenate([known_sides, sides[inside]]),
        )
        return Starts(values[:, None], q, margins, np.zeros(len(values)))


def evaluate_starts(
    robot: Robot,
    path: Segment | Chain,
    objective: Objective,
    held: str | Sequence[str],
    values: np.ndarray | Starts,
    checked: tuple[str, ...] | None = None,
    tolerance: float = TOLERANCE,
    stop_past: bool = False,
    method: str = "sweep",
    circuit: bool = False,
    extending: bool = False,
) -> SearchResult:
    """Steps iv-v along ``path`` (a segment, or a cycle's `Chain`) for the given held values,
    (k,) for one held actuator or (k, r), or for `Starts` already found: integrate the
    reachable ones as one batch, check the limits, take the objective. ``stop_past`` stops
    motions that, with both neighbours in the batch, are past a checked stroke (their margin is
    then unknown, −inf). A start is feasible where its margin μ (the motion's and the start's
    joint margin) is ≥ −`LIMIT_TOLERANCE` and the motion kept every other checked limit: with
    ``circuit`` also the hydraulic circuit's (its margin stays the strokes'). No reachable start
    is an `UnreachableError`, unless the batch is ``extending`` a search (a refinement's probes
    between samples): then they are samples as any unreachable one, and no motion."""
    path, objective = checked_path(path, "path"), as_objective(objective)
    held = held_names(robot, held)
    starts = values
    if not isinstance(starts, Starts):  # by multi-seed inverse kinematics
        values = np.asarray(values, dtype=float).reshape(-1, len(held))
        ik = inverse_kinematics(robot, path.start, held, values)
        margins = np.where(ik.reached, 0.0, -np.inf)
        starts = Starts(values, ik.q, margins, np.where(ik.reached, 0.0, ik.miss))
    reachable = np.flatnonzero(starts.reachable)
    rows = np.full(len(starts.values), -1)
    rows[reachable] = np.arange(reachable.size)
    if not reachable.size:
        if not extending:
            miss = starts.miss[starts.miss > 0]
            how = f"from any of the {len(starts.values)} sampled values of {', '.join(held)}"
            raise _unreachable(robot, path, how, miss.min() if miss.size else None)
        unreached = tuple(starts.sample(i) for i in range(len(rows)))
        return SearchResult(robot, path, objective, held, unreached, (), rows, method)
    motions = simulate_path(
        robot,
        objective.resolver,
        path,
        starts.q[reachable],
        checked=checked,
        tolerance=tolerance,
        objective=objective,
        sparse=True,
        stop_past=stop_past,
        circuit=circuit,
    )
    scores, margins, within = motions.score(objective), motions.margins, motions.within_limits
    samples = []
    for i, row in enumerate(rows):
        if row < 0:
            samples.append(starts.sample(i))
            continue
        start = tuple(float(v) for v in starts.values[i])
        margin = float(min(margins[row], starts.joint_margins[i]))
        feasible = margin >= -LIMIT_TOLERANCE and bool(within[row])
        found = tuple(motions.violations(row))
        reason = None if feasible else _reason(motions, row, found)
        samples.append(Sample(start, float(scores[row]), feasible, margin, found, reason))
    return SearchResult(robot, path, objective, held, tuple(samples), (motions,), rows, method)


def _reason(trajectory: Trajectory, row: int, violations: tuple[Violation, ...]) -> str:
    """Why a reachable start is not feasible."""
    if trajectory.failed[row]:
        return f"the motion failed {FAILED}"
    if trajectory.stopped[row]:
        return "past a stroke limit, as its neighbours: stopped"
    if violations:
        return str(max(violations, key=lambda v: v.excess))
    return (
        f"within the integration allowance ({amount(trajectory.allowance, 'm')}) of a stroke limit"
    )


def improved_start(
    robot: Robot,
    segment: Segment | Chain,
    objective: Objective,
    held: str | Sequence[str] | None = None,
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    tolerance: float | None = None,
    circuit: bool = False,
) -> SearchResult:
    """The paper's improved initial configuration (steps i-v), searching the held actuators
    ``held`` (one name, or several; by default a work cycle's task's, else the last n − m:
    `held_actuators`).

    ``method`` "fast" (the default for one held actuator) or "sweep" (the default, and the only
    method, for several): see the module docstring. ``samples`` is the sweep's count (the
    fast search's budget is its own). ``checked`` restricts the limit check to named actuators
    (the paper's step iv checks x1 and x2); by default every actuator counts. ``tolerance``
    (m, or rad) locates the fast search's feasible ends; default `END_TOLERANCE` of the stroke.
    With ``circuit`` a start must also keep the robot's hydraulic circuit within its limits
    (load pressures, pump flow, cylinder speeds): the fast search then bisects where those bind.
    """
    (search,) = improved_starts(
        robot, segment, (objective,), held, samples, checked, method, tolerance, circuit
    )
    return search


def improved_starts(
    robot: Robot,
    segment: Segment | Chain,
    objectives: Sequence[Objective],
    held: str | Sequence[str] | None = None,
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    tolerance: float | None = None,
    circuit: bool = False,
) -> tuple[SearchResult, ...]:
    """`improved_start` for each of ``objectives`` on one segment, in order. The start
    configurations do not depend on the objective, so the searches share them: the fast
    search's reachable scan is done once."""
    require_robot(robot)
    segment = checked_path(segment)
    objectives = objectives_of(objectives)
    held = chosen_held(robot, segment, held)
    method = search_method(held, samples, method)

    def run(objective, starts, stop_past=False, extending=False):
        return evaluate_starts(
            robot,
            segment,
            objective,
            held,
            starts,
            checked,
            TOLERANCE,
            stop_past,
            method,
            circuit,
            extending,
        )

    if len(held) > 1:
        return tuple(
            _compass(robot, segment, held, samples, partial(run, objective))
            for objective in objectives
        )
    if method == "fast":
        tolerance = end_tolerance(robot, held[0], tolerance)
    Limits.strokes(robot, checked)  # names checked before any work
    branches = Configurations.branches(robot, segment, held[0])
    if method == "fast":
        return tuple(
            _best_branch(
                partial(fast_search, branch, tolerance, partial(run, objective))
                for branch in branches
            )
            for objective in objectives
        )
    if samples == 1:  # the default start: mid-stroke, or the reachable value nearest it
        branches, values = branches[:1], default_start(robot, segment, held)[0]
    else:
        values = sweep_values(robot, held[0], samples)
    starts = [branch.at(values) for branch in branches]
    return tuple(
        _best_branch(partial(run, objective, each) for each in starts) for objective in objectives
    )


def _best_branch(searches: Iterable[Callable[[], SearchResult]]) -> SearchResult:
    """Of the searches of each assembly branch, the one whose best start has the least peak
    (or integral) over its motion on the grid (`SearchResult.best_peak`: the samples' figures
    can miss a peak between them by a per cent, more than branches may differ) or, where no
    start is feasible on any, the highest margin; the first branch on a tie within `TIE`
    (branches mirror each other on a symmetric task). A branch with no reachable start is
    left out unless none has one. One branch is returned as it is, its motion not computed."""
    found: list[SearchResult] = []
    failure: UnreachableError | None = None
    for search in searches:
        try:
            found.append(search())
        except UnreachableError as error:
            failure = failure or error
    if not found:
        raise cast(UnreachableError, failure)

    if len(found) == 1:
        return found[0]

    def rank(result: SearchResult) -> tuple[float, float]:
        if result.best is not None:
            return 0.0, cast(float, result.best_peak)
        return 1.0, -max(sample.margin for sample in result.samples)

    ranks = [rank(result) for result in found]
    kind, least = min(ranks)
    return next(r for r, k in zip(found, ranks) if k <= (kind, least + TIE * abs(least)))


def search_method(held: tuple[str, ...], samples: int, method: str | None) -> str:
    """The search for ``held``: ``method``, or by default "fast" for one held actuator and
    "sweep" for several; one line where it or the ``samples`` count is not valid."""
    if not is_whole(samples, 1, MAX_SAMPLES):
        raise InvalidInputError(
            f"samples must be a whole number within [1, {MAX_SAMPLES:,}]; got {samples!r}"
        )
    method = method or ("fast" if len(held) == 1 else "sweep")
    if method not in METHODS:
        raise InvalidInputError(f"unknown method {method!r}; methods: {', '.join(METHODS)}")
    if method == "fast" and len(held) != 1:
        raise InvalidInputError(
            f"the fast search holds one actuator; {list(held)} are {len(held)}: use the sweep "
            "(method='sweep', --method sweep)"
        )
    return method


def end_tolerance(robot: Robot, held: str, tolerance: float | None) -> float:
    """The tolerance (m or rad) to which the fast search locates the feasible ends:
    ``tolerance``, or by default `END_TOLERANCE` of the held actuator's stroke."""
    if tolerance is None:
        lower, upper = stroke_box(robot, (held,))[0]
        tolerance = END_TOLERANCE * (upper - lower)
    if not (is_finite(tolerance) and tolerance > 0):
        raise InvalidInputError(
            f"tolerance must be a finite number > 0 (m or rad); got {tolerance!r}"
        )
    return tolerance


def fast_search(configurations: Configurations, tolerance: float | None, evaluate):
    """The fast search for one held actuator (see the module docstring) over the start
    ``configurations`` of a path: ``evaluate(starts, stop_past, extending)`` integrates `Starts`
    along it and returns a search of their samples that can be ``extended``. The reachable scan
    is the configurations' own, shared by every search that uses them."""
    tolerance = end_tolerance(configurations.robot, configurations.held, tolerance)
    pieces = configurations.reachable(tolerance)
    grid = configurations.at(grid_over(pieces, GRID))
    spacing = np.sum(pieces[:, 1] - pieces[:, 0]) / (GRID - 1)
    search = evaluate(grid, True)
    if not search.feasible:  # between the grid's values, if anywhere: climb the margin there
        if not np.isfinite([s.margin for s in search.samples]).any():  # all stopped: unknown
            search = evaluate(grid, False)
        for _ in range(ROUNDS):
            _, values, margins = _by_value(search)
            probes = new_probes(summit_probes(values, margins, tolerance), values, tolerance)
            if search.feasible or not probes.size:
                break
            search = search.extended(evaluate(configurations.at(probes), False, True))
    for _ in range(ROUNDS):
        ordered, values, margins = _by_value(search)
        feasible = np.array([s.feasible for s in ordered])
        peaks = np.array([s.peak if s.feasible else np.inf for s in ordered])
        candidates = bracket_probes(values, margins, feasible, tolerance)
        candidates += vertex_probes(values, peaks, tolerance)
        candidates += end_probe(values, peaks, spacing)
        probes = new_probes(candidates, values, tolerance)
        if not probes.size:
            break
        starts = configurations.at(probes)
        search = search.extended(evaluate(starts, False, True))
    return search


def _by_value(search: SearchResult) -> tuple[list[Sample], np.ndarray, np.ndarray]:
    """A one-held-actuator search's samples in order of their value, with their values and
    margins (k,) each."""
    ordered = [search.samples[i] for i in np.argsort(search.values[:, 0], kind="stable")]
    return ordered, np.array([s.value for s in ordered]), np.array([s.margin for s in ordered])


def _compass(robot, segment, held, samples, run) -> SearchResult:
    """Halton points over the stroke box, then compass-search refinement (r > 1), the held
    values (k, r) of each batch integrated by ``run``."""
    box = stroke_box(robot, held)
    span = box[:, 1] - box[:, 0]
    if samples == 1:  # one sample is the default start, as with one held actuator
        result = run(default_start(robot, segment, held)[0][None])
    else:
        try:
            result = run(_halton(box, samples, seed=1))
        except UnreachableError:  # the reachable starts lie between the samples, if anywhere
            reached = free_held_values(robot, segment, held)
            if not len(reached):
                raise
            result = run(reached)
    leaders = sorted(result.feasible, key=lambda s: s.peak)[:REFINED_AROUND]  # type: ignore[arg-type,return-value]
    step = 1 / samples ** (1 / len(held))  # fraction of each stroke
    for turn in _poll_bases(len(held), REFINEMENT_ROUNDS):
        if not leaders or step < FINEST_STEP:
            break
        directions = np.concatenate([turn, -turn])
        centres = np.array([s.values for s in leaders])
        trials = centres[:, None] + step * span * directions  # (leaders, 2r, r)
        tried = run(np.clip(trials, box[:, 0], box[:, 1]).reshape(-1, len(held)), extending=True)
        result = result.extended(tried)
        improved = False
        for i, leader in enumerate(leaders):
            options = tried.samples[i * len(directions) : (i + 1) * len(directions)]
            better = [s for s in options if s.feasible and s.peak < leader.peak]  # type: ignore[operator]
            if better:
                leaders[i] = min(better, key=lambda s: s.peak)  # type: ignore[arg-type,return-value]
                improved = True
        if not improved:
            step /= 2
    return result


def free_held_values(robot: Robot, path: Segment | Chain, held: tuple[str, ...]) -> np.ndarray:
    """The held actuators' values (j, r), inside their strokes, of the configurations that
    reach the start of ``path`` with every actuator free (`free_configurations`, from
    `ANCHOR_SEEDS` seeds): starts for a search whose samples of the stroke box all miss the
    set of held values that reaches it, a small part of the box where r is large."""
    q, _ = free_configurations(robot, path.start, ANCHOR_SEEDS)
    rows = held_indices(robot, held)
    values = evaluate(robot, q).x[:, rows] if len(q) else np.empty((0, len(held)))
    box = stroke_box(robot, held)
    inside = np.all((values >= box[:, 0]) & (values <= box[:, 1]), axis=1)
    return values[inside].reshape(-1, len(held))


def _poll_bases(r: int, rounds: int) -> np.ndarray:
    """The orthonormal bases (rounds, r, r) the compass search polls along, ± each row, one a
    round: the Householder matrices H = I − 2 v vᵀ / vᵀv of v = 2u − 1, u the round's point of
    the (unscrambled) Halton sequence, as in OrthoMADS (Abramson, Audet, Dennis and Le Digabel,
    SIAM J. Optim. 20(2), 2009). The first is the held actuators' own axes; the next ones turn,
    and over the rounds the directions fill the sphere, so that a leader in a narrow oblique
    valley of the peak, or on a limit that crosses the strokes obliquely, still finds the way
    along it, where polls along the strokes alone stall."""
    from scipy.stats import qmc

    v = 2 * qmc.Halton(r, scramble=False).random(rounds) - 1
    return np.eye(r) - 2 * v[:, :, None] * v[:, None, :] / np.sum(v * v, axis=1)[:, None, None]


def _halton(box: np.ndarray, count: int, seed: int) -> np.ndarray:
    """``count`` scrambled Halton points over the stroke ``box`` (r, 2), (count, r)."""
    from scipy.stats import qmc

    return qmc.scale(qmc.Halton(len(box), seed=seed).random(count), box[:, 0], box[:, 1])


def default_start(robot: Robot, segment: Segment | Chain, held: str | Sequence[str] | None = None):
    """The documented default start: the held actuators (by default `held_actuators`) at
    mid-stroke or, where the segment's start is out of reach there, the reachable candidate
    nearest mid-stroke (candidates: 101 values per held actuator for one, 256 Halton points for
    several; where none reaches it, the held values of configurations that reach it with every
    actuator free, `free_held_values`).

    Returns (values (r,), q (n,)).
    """
    require_robot(robot)
    segment = checked_path(segment)
    held = chosen_held(robot, segment, held)
    box = stroke_box(robot, held)
    if len(held) == 1:
        candidates = sweep_values(robot, held[0], 101)[:, None]
    else:
        candidates = _halton(box, 256, seed=3)
    middle, span = box.mean(axis=1), box[:, 1] - box[:, 0]
    miss = np.inf
    # the candidates; where none reaches it, the held values of free configurations
    for found in (lambda: candidates, lambda: free_held_values(robot, segment, held)):
        values = found()
        ordered = values[
            np.argsort(np.linalg.norm((values - middle) / span, axis=1), kind="stable")
        ]
        tried = 0
        while tried < len(ordered):  # nearest first, in batches doubling in size: 1, 2, 4, ...
            batch = ordered[tried : 2 * tried + 1]
            ik = inverse_kinematics(robot, segment.start, held, batch)
            if ik.reached.any():
                first = int(np.argmax(ik.reached))
                return batch[first], ik.q[first]
            tried, miss = tried + len(batch), min(miss, float(ik.miss.min()))
    raise _unreachable(robot, segment, f"with {', '.join(held)} anywhere in their strokes", miss)


def scalar_or_list(values):
    """One held actuator's value as a number, several as a list (the report's shape)."""
    values = [float(v) for v in values]
    return values[0] if len(values) == 1 else values
