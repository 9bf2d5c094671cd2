"""The paper's study: every segment of a work cycle, each objective's improved initial
configuration and its bound, and the strategies it is compared with, as one report.

For each segment and objective:
- the improved start, by the fast search (or, with ``method="sweep"``, the paper's uniform
  sweep), and its motion;
- the sweep's curve of the objective against the held value (the paper's Figs. 4a, 5a),
  integrated adaptively as one batch;
- the bound: the global optimum over every history of the held actuator
  (`redundancy.planning.bound`), and the improved start's gap to it, in per cent.

For each segment the comparison holds, with both peaks and whether every limit held:
- the unweighted and (where the robot has masses) the M_H-weighted pseudoinverse from the
  default start (the held actuator at mid-stroke, or the reachable value nearest it:
  `default_start`);
- gradient projection with actuator-limit avoidance from the same start (the paper's baseline);
- the improved method for each objective;
- with a hydraulic circuit, each motion's peak pump flow, highest load pressure and pump energy
  under load sensing and constant pressure, and, when asked for, how far each lies above the
  energy bound of each supply (`redundancy.planning.integral_optimum`).

Where the task is one continuous closed cycle, the study's cycle section runs it as a machine
does, for the first objective (`redundancy.study.cycles`): the improved start over the whole
cycle beside the per-segment plan and its corners' self-motions, the free and the drift-free
strategies repeated, their drift and their price.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from functools import cached_property, partial
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.hydraulics import KILOJOULE, SUPPLIES
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.bound import GlobalOptimum, global_optimum
from redundancy.planning.ik import check_path
from redundancy.planning.integral_optimum import EnergyOptimum, energy_optimum
from redundancy.planning.integrate import Trajectory
from redundancy.planning.starts import (
    METHODS,
    Sample,
    SearchResult,
    default_start,
    held_actuators,
    improved_starts,
    scalar_or_list,
)
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.laws import GradientProjection, Resolver
from redundancy.resolution.objectives import ENERGY, VELOCITY, Objective, objectives_of
from redundancy.study.check import check, reachable_points
from redundancy.study.cycles import CycleStudy, noted, report_header, run_cycle, search_report
from redundancy.study.output import write_atomically
from redundancy.study.peers import StrategyRun, fixed_start_run

NOT_ASKED = "the study was run without bounds"  # a bound's reason, `bound=False`
INTEGRAL = (  # an integral objective's: its optimum by dynamic programming takes about a minute
    # per segment on the crane, left to `integral_optimum`
    "the min-max bound bounds peaks; an integral's least value: redundancy.integral_optimum (the "
    "pump energy's within the circuit: --energy-bound)"
)
STUDY_CYCLES = 3  # the cycle section's repetitions: enough to show the drift; `redundancy cycle`
# runs `redundancy.planning.cycles.CYCLES` (20), at about 0.3 s per cycle of the crane

BASELINES: tuple[tuple[str, Resolver], ...] = (
    ("unweighted, default start", VELOCITY.resolver),
    ("M_H-weighted, default start", ENERGY.resolver),
    ("gradient projection, default start", GradientProjection()),
)


@dataclass(frozen=True)
class Study:
    """Per objective and segment: the search that chose the improved start, the sweep behind
    the figures (the same search with ``method="sweep"``) and the bound (None where no start is
    feasible or the bound was not asked for); and the strategy comparison."""

    robot: Robot
    cycle: WorkCycle
    held: tuple[str, ...]
    samples: int
    method: str
    checked: tuple[str, ...]
    circuit: bool
    searches: dict[str, tuple[SearchResult, ...]]
    sweeps: dict[str, tuple[SearchResult, ...]]
    bounds: dict[str, tuple[GlobalOptimum | None, ...]]
    runs: tuple[StrategyRun, ...]
    energy_bounds: dict[str, dict[str, EnergyOptimum]] | None = None  # segment → supply → bound
    bound_failures: dict[str, str] | None = None  # "objective/segment", or "energy bound
    # LS/segment", → why it has no bound
    cycle_study: CycleStudy | None = None  # the cycle section (None: not run, see cycle_skipped)
    cycle_skipped: str | None = None  # why the study has no cycle section
    reachable: np.ndarray | None = None  # (k, m) task points reached with the strokes kept,
    # sampled (`reachable_points`); None where the task has no plane
    nonoptimal_motions: dict[str, tuple[Sample, Trajectory] | None] = field(
        default_factory=dict, repr=False, compare=False
    )  # by segment, `nonoptimal`'s start and motion (None: no feasible start), once computed

    def search(self, objective: str, segment: str) -> SearchResult:
        return self.searches[objective][self._segment(segment)]

    @property
    def best_motions(self) -> dict[tuple[str, str], Trajectory]:
        """The motion from each improved start, as the study ran it, by (objective, segment)
        where the segment has a feasible start: what the playbacks show and the time series
        export."""
        return {
            (name, search.segment.name): search.best_motion
            for name, searches in self.searches.items()
            for search in searches
            if search.best is not None
        }

    @cached_property
    def best_poses(self) -> dict[tuple[str, str], np.ndarray]:
        """The machine at each improved start, by (objective, segment), as rods between its
        joints' origins and to the tool (`Robot.skeleton`, (R, 2, 3) in m): what the workspace
        figure draws."""
        return {
            key: self.robot.skeleton(motion.q[0, :1])[0]
            for key, motion in self.best_motions.items()
        }

    def sweep(self, objective: str, segment: str) -> SearchResult:
        return self.sweeps[objective][self._segment(segment)]

    def shown_segment(self, objective: str) -> str | None:
        """The segment whose motions the figures show for ``objective`` (the paper's Figs. 4b,
        4c and 5b, and the circuit along the best motion): the first with an improved start,
        as the paper's 1-2; None where no segment has one."""
        searches = self.searches[objective]
        return next((s.segment.name for s in searches if s.best is not None), None)

    def nonoptimal(self, segment: str) -> tuple[Sample, Trajectory] | None:
        """The paper's Fig. 4c start on ``segment``, the velocity sweep's least extended feasible
        start, and its motion on the grid, computed once (the study computes it on the
        velocity objective's `shown_segment`); None where the sweep has no feasible start."""
        if segment not in self.nonoptimal_motions:
            sweep = self.sweep(VELOCITY.name, segment)
            start = min(sweep.feasible, key=lambda s: s.values, default=None)
            motion = None if start is None else (start, sweep.motion(start))
            self.nonoptimal_motions[segment] = motion
        return self.nonoptimal_motions[segment]

    def bound(self, objective: str, segment: str) -> GlobalOptimum | None:
        """The bound as solved, converged or not (see `result`)."""
        return self.bounds[objective][self._segment(segment)]

    def withheld(self, objective: str, segment: str) -> str | None:
        """Why ``segment``'s bound of ``objective`` is no result, in one line, or None: the
        bound failed, or it is withheld against the improved start's peak
        (`GlobalOptimum.withheld`)."""
        failure = (self.bound_failures or {}).get(f"{objective}/{segment}")
        bound = self.bound(objective, segment)
        if failure is not None or bound is None:
            return failure
        return bound.withheld(self.search(objective, segment).best_peak)

    def result(self, objective: str, segment: str) -> GlobalOptimum | None:
        """The bound where it is a result (not `withheld`), else None."""
        withheld = self.withheld(objective, segment)
        return None if withheld is not None else self.bound(objective, segment)

    def energy_withheld(self, segment: str, supply: str) -> str | None:
        """Why ``segment``'s energy bound under ``supply`` is no result, in one line, or None:
        the bound failed or did not converge (`Refined.failure`)."""
        failure = (self.bound_failures or {}).get(f"energy bound {supply}/{segment}")
        bound = (self.energy_bounds or {}).get(segment, {}).get(supply)
        return failure if failure is not None or bound is None else bound.failure

    def energy_result(self, segment: str, supply: str) -> EnergyOptimum | None:
        """The energy bound where it is a result (not `energy_withheld`), else None."""
        bound = (self.energy_bounds or {}).get(segment, {}).get(supply)
        return None if self.energy_withheld(segment, supply) is not None else bound

    def _segment(self, name: str) -> int:
        names = [s.name for s in self.cycle.segments]
        if name not in names:
            raise InvalidInputError(f"no segment {name!r}; segments: {', '.join(names)}")
        return names.index(name)

    def gap(self, objective: str, segment: str) -> float | None:
        """(improved peak − bound) / bound, in per cent, or None."""
        peak, bound = self.search(objective, segment).best_peak, self.result(objective, segment)
        if peak is None or bound is None:
            return None
        return 100 * (peak - bound.bound) / bound.bound

    def report(self) -> dict:
        """The study as JSON-ready data."""
        return {
            **report_header(self.robot, self.cycle, self.checked, self.circuit),
            "samples": self.samples,
            "method": self.method,
            "studies": [
                {
                    "objective": name,
                    "measure": searches[0].objective.value_label if searches else None,
                    "unit": searches[0].objective.value_unit(self.robot.actuators)
                    if searches
                    else None,
                    "segments": [
                        self._segment_report(name, search.segment.name) for search in searches
                    ],
                }
                for name, searches in self.searches.items()
            ],
            "comparison": [self._run_report(run) for run in self.runs],
            **({} if self.energy_bounds is None else {"energy_bounds": self._energy_report()}),
            "bound_failures": self.bound_failures or {},
            "cycle": self.cycle_study.report()
            if self.cycle_study is not None
            else {"skipped": self.cycle_skipped},
        }

    def above_energy_bound(self, run: StrategyRun) -> dict[str, float]:
        """How far ``run``'s pump energy lies above the energy bound of each supply where that
        bound is a result, per cent (empty without energy bounds)."""
        if self.energy_bounds is None or run.segment not in self.energy_bounds:
            return {}
        energies = run.summary()["hydraulics"]
        return {
            supply: 100 * (energies[f"{supply.lower()}_energy_kj"] * KILOJOULE / b.energy - 1)
            for supply in self.energy_bounds[run.segment]
            if (b := self.energy_result(run.segment, supply)) is not None
        }

    def _run_report(self, run: StrategyRun) -> dict:
        summary = run.summary()
        if above := self.above_energy_bound(run):
            summary["hydraulics"]["above_energy_bound_percent"] = above
        return summary

    def _energy_report(self) -> dict:
        """Each segment's energy bound under each supply, one whose solve raised too: its
        figures null, its failure the reason."""
        return {
            segment: {
                supply: {
                    "energy_kj": None if result is None else result.energy / KILOJOULE,
                    "change": None if bound is None else bound.change,
                    "converged": bound is not None and bound.converged,
                    "grids": [] if bound is None else [g.intervals for g in bound.grids],
                    "start": None if result is None else scalar_or_list(np.atleast_1d(result.r[0])),
                    "failure": self.energy_withheld(segment, supply),
                }
                for supply in SUPPLIES
                for bound in [bounds.get(supply)]
                for result in [self.energy_result(segment, supply)]
            }
            for segment, bounds in (self.energy_bounds or {}).items()
        }

    def _segment_report(self, objective: str, segment: str) -> dict:
        search, sweep = self.search(objective, segment), self.sweep(objective, segment)
        bound = self.result(objective, segment)
        return {
            "name": segment,
            "start": search.segment.start.tolist(),
            "end": search.segment.end.tolist(),
            "held_actuator": search.held[0] if len(search.held) == 1 else list(search.held),
            **search_report(search, sweep),
            "bound": None
            if bound is None
            else {
                "peak": bound.bound,
                "start": bound.start,
                "change": bound.change,
                "converged": bound.converged,
            },
            "gap_percent": self.gap(objective, segment),
            "bound_failure": self.withheld(objective, segment),
            "samples": [
                {
                    "value": scalar_or_list(s.values),
                    "peak": s.peak,
                    "feasible": s.feasible,
                    "reason": s.reason,
                }
                for s in sweep.samples
            ],
        }


@dataclass(frozen=True)
class Searches:
    """A study's improved start searches, made first (`study_searches`), so that the cycle
    section's per-segment plan reads the first objective's instead of searching again: per
    segment (by name), one search per objective, each with the best start's motion; the held
    actuators and the method as searched, and ``given`` the arguments they were searched with."""

    held: tuple[str, ...]
    method: str
    by_segment: dict[str, tuple[SearchResult, ...]]
    given: tuple

    def first(self) -> tuple[SearchResult, ...]:
        """The first objective's search on each segment: the cycle section's per-segment plan."""
        return tuple(searches[0] for searches in self.by_segment.values())


def _given(objectives: tuple[Objective, ...], *arguments) -> tuple:
    """What `Searches.given` records: the objectives' names and the other search arguments, so
    that `run_study` can tell searches made with other arguments."""
    return (tuple(o.name for o in objectives), *arguments)


def study_searches(
    robot: Robot,
    cycle: WorkCycle,
    objectives: tuple[Objective, ...] = (VELOCITY, ENERGY),
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    energy_bound: bool = False,
    circuit: bool = False,
) -> Searches:
    """Every segment's improved start search for each of ``objectives`` (`improved_starts`),
    and each best start's motion, as `run_study` makes them with these arguments; bad input is
    refused first, as `run_study` refuses it."""
    objectives = objectives_of(objectives)
    held = held_actuators(robot, cycle)
    searched = method or ("fast" if len(held) == 1 else "sweep")
    if searched not in METHODS:
        raise InvalidInputError(f"unknown method {searched!r}; methods: {', '.join(METHODS)}")
    _refuse_before_work(robot, cycle, held, energy_bound, circuit)
    by_segment = {
        segment.name: improved_starts(
            robot, segment, objectives, held, samples, checked, searched, circuit=circuit
        )
        for segment in cycle.segments
    }
    for searches in by_segment.values():
        for search in searches:
            if search.best is not None:
                search.best_motion  # noqa: B018 -- computed once, before a fork shares it
    given = _given(objectives, samples, checked, method, energy_bound, circuit)
    return Searches(held, searched, by_segment, given)


def run_study(
    robot: Robot,
    cycle: WorkCycle,
    objectives: tuple[Objective, ...] = (VELOCITY, ENERGY),
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    bound: bool = True,
    progress: bool = True,
    energy_bound: bool = False,
    circuit: bool = False,
    cycles: int = STUDY_CYCLES,
    searches: Searches | None = None,
) -> Study:
    """Run every objective's improved search, sweep and bound, and the comparison strategies,
    on every segment.

    The held actuators are the task's ``held`` or, if it names none, the last n − m actuators
    (`held_actuators`). ``method`` chooses the improved start: "fast" (the default with one
    held actuator) or "sweep" (``samples`` starts; always with several). The bound is computed
    where a start is feasible, unless ``bound`` is False. With ``energy_bound`` (one or two
    held actuators and a hydraulic circuit), each segment's energy bound under load sensing and
    constant pressure is computed too. With ``circuit`` the hydraulic
    circuit's limits count wherever strokes do (the searches' feasibility, every run's limits);
    the min-max bound still keeps the strokes alone, so it stays a bound. With ``cycles`` > 0
    and a continuous closed task, the cycle section repeats the cycle that many times for the
    first objective (`run_cycle`), its per-segment plan from the study's searches; 0 leaves it
    out. ``searches``: the improved searches already made by `study_searches` with the same
    arguments (by default made here). A bound that fails does not stop the study: why is kept
    in `Study.bound_failures`.
    """
    require_robot(robot)
    from tqdm import tqdm

    objectives = objectives_of(objectives)
    given = _given(objectives, samples, checked, method, energy_bound, circuit)
    if searches is None:
        searches = study_searches(
            robot, cycle, objectives, samples, checked, method, energy_bound, circuit
        )
    elif searches.given != given:
        raise InvalidInputError(
            f"the searches were made with {searches.given}; this study's arguments are {given}"
        )
    held, searched = searches.held, searches.method
    baselines = [
        (n, r) for n, r in BASELINES if not (robot.kinematic_only and r is ENERGY.resolver)
    ]
    on_segment = partial(_on_segment, robot, objectives, held, samples, checked, circuit, baselines)
    failures: dict[str, str] = {}
    total = len(cycle.segments) * (len(baselines) + 3 * len(objectives))
    with tqdm(total=total, unit="task", desc="study", disable=not progress, mininterval=0.5) as bar:
        parts = [
            on_segment(segment, searches.by_segment[segment.name], searched, bound, bar, failures)
            for segment in cycle.segments
        ]
    energy_bounds: dict[str, dict[str, EnergyOptimum]] | None = None
    if energy_bound:
        machine, energy_bounds = robot.circuit(), {}
        for segment in tqdm(cycle.segments, desc="energy bounds", disable=not progress):
            found = energy_bounds[segment.name] = {}
            for supply in machine.supplies:
                with noted(failures, f"energy bound {supply.name}/{segment.name}"):
                    found[supply.name] = energy_optimum(robot, segment, supply, held, checked)
    runs = tuple(run for part in parts for run in part[0])
    for run in runs:  # every figure a report or table shows is computed here, once
        run.summary()
    cycle_study, skipped = cycle_section(
        robot,
        cycle,
        objectives[0],
        cycles,
        samples,
        checked,
        method,
        circuit,
        progress,
        searches.first(),
    )
    kept = tuple(robot.actuators.names if checked is None else checked)

    def by_objective(k: int) -> dict[str, tuple]:
        return {o.name: tuple(part[k][i] for part in parts) for i, o in enumerate(objectives)}

    study = Study(
        robot,
        cycle,
        held,
        samples,
        searched,
        kept,
        circuit,
        by_objective(1),
        by_objective(2),
        by_objective(3),
        runs,
        energy_bounds,
        failures,
        cycle_study,
        skipped,
        reachable_points(robot, kept) if len(robot.task_axes) >= 2 else None,
    )
    shown = study.shown_segment(VELOCITY.name) if VELOCITY.name in study.sweeps else None
    if shown is not None:  # the figures' Fig. 4c
        study.nonoptimal(shown)
    return study


def _on_segment(
    robot,
    objectives,
    held,
    samples,
    checked,
    circuit,
    baselines,
    segment,
    searches,
    method,
    bound,
    bar,
    failures,
) -> tuple[list[StrategyRun], list[SearchResult], list[SearchResult], list]:
    """One segment's part of the study: the runs (the ``baselines`` from the default start, the
    improved starts'), and per objective its search (``searches``, made by ``method``), its
    sweep and its bound (a failure noted in ``failures``); ``bar`` counts them."""
    start = default_start(robot, segment, held)
    runs = []
    for name, resolver in baselines:
        bar.set_description(f"{segment.name}: {name}")
        runs.append(
            fixed_start_run(robot, resolver, name, segment, held, start, checked, circuit=circuit)
        )
        bar.update()
    sweeps = searches
    if method == "fast":
        bar.set_description(f"{segment.name}: sweeps")
        sweeps = improved_starts(
            robot, segment, objectives, held, samples, checked, "sweep", circuit=circuit
        )
    bar.update(2 * len(objectives))
    bounds = []
    for objective, search in zip(objectives, searches):
        optimum = None
        if search.best is not None:
            strategy = f"improved, {objective.name} objective"
            runs.append(StrategyRun(segment.name, strategy, search.best.values, search.best_motion))
            if objective.reduction != "peak":
                failures[f"{objective.name}/{segment.name}"] = INTEGRAL
            elif not bound:
                failures[f"{objective.name}/{segment.name}"] = NOT_ASKED
            else:
                bar.set_description(f"{segment.name}: bound, {objective.name}")
                with noted(failures, f"{objective.name}/{segment.name}"):
                    optimum = global_optimum(
                        robot, segment, objective, held, checked, search=search
                    )
        bounds.append(optimum)
        bar.update()
    return runs, list(searches), list(sweeps), bounds


def _refuse_before_work(robot, cycle, held, energy_bound: bool, circuit: bool) -> None:
    """A missing circuit, an energy bound on more than two held actuators, or a path out of
    reach is refused before any simulation; a singular actuator is warned of (J_H = J A⁻¹
    is undefined there: motions through it fail, and say so)."""
    if energy_bound or circuit:
        robot.circuit()  # says how to declare one
    if energy_bound and len(held) > 2:
        raise InvalidInputError(
            f"the energy bound holds one or two actuators; the task holds {held}"
        )
    for segment in cycle.segments:
        check_path(robot, segment)
    singular = [line for a in check(robot).actuators for line in a.singular_lines()]
    if singular:
        warnings.warn("; ".join(singular), stacklevel=3)


def cycle_section(
    robot: Robot,
    cycle: WorkCycle,
    objective: Objective,
    cycles: int = STUDY_CYCLES,
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    circuit: bool = False,
    progress: bool = False,
    segments: tuple[SearchResult, ...] | None = None,
) -> tuple[CycleStudy | None, str | None]:
    """The study's cycle section: `run_cycle` for ``objective``, repeating the cycle ``cycles``
    times, where the task is one continuous closed cycle; ``segments``: the per-segment plan's
    searches where the study made them (`Searches.first`). Returns the cycle study, or None and
    why there is none (``cycles`` = 0, or the task does not close)."""
    if not cycles:
        return None, "not asked for (cycles = 0)"
    try:
        cycle.check_continuous(closed=True)
    except InvalidInputError as error:
        return None, str(error)
    found = run_cycle(
        robot,
        cycle,
        objective,
        cycles,
        samples=samples,
        checked=checked,
        method=method,
        circuit=circuit,
        progress=progress,
        segments=segments,
    )
    return found, None


def write_report(study: Study | CycleStudy, path: Path) -> None:
    """The JSON report of a study, or of a cycle study (`run_cycle`), written atomically."""
    text = json.dumps(study.report(), indent=1, allow_nan=False)
    write_atomically(path, lambda p: p.write_text(text + "\n"))
