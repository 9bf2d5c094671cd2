"""The work cycle as a machine runs it, as one report: `redundancy cycle` and the study's cycle
section. For one objective (a peak one for the drift-free strategy): the plan (`plan_cycle`);
the strategies, each repeated for ``cycles`` cycles (`repeat`): "free", the objective's law
from the whole-cycle improved start, which drifts, and "periodic", the drift-free periodic
optimum (`periodic_optimum`) run by the law that follows its plan; the drift, settling and
return map; and the drift-free strategy's price against the free one, in the objective's peak
and, with hydraulics, the pump energy under load sensing and constant pressure, and the limits
of the circuit and of the cylinders' accelerations each strategy's first cycle passes
(`circuit_violations`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.cycles import (
    CYCLES,
    SETTLED,
    STRATEGIES,
    Corner,
    CyclePlan,
    FixedPoint,
    PeriodicOptimum,
    Repetition,
    ReturnMap,
    checked_cycles,
    cycle_accelerations,
    periodic_optimum,
    plan_cycle,
    repeat,
    return_map,
)
from redundancy.planning.ik import named_values
from redundancy.planning.integrate import Trajectory
from redundancy.planning.starts import SearchResult, default_start, held_actuators, scalar_or_list
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.limits import Limits, Violation, amount
from redundancy.resolution.objectives import VELOCITY, Objective
from redundancy.resolution.objectives import objective as as_objective
from redundancy.study.peers import pump_energies

CHOICES = (*STRATEGIES, "both")


def free_start_of(search: SearchResult) -> tuple[str, np.ndarray, str]:
    """The start the free strategy runs from: the whole-cycle improved start; where no start
    keeps every stroke over the cycle, the closest one (the reached start whose worst excess is
    least, the one `SearchResult.closest_violation` names); where none was reached, the default
    start. Returns its kind, its configuration (n,) and its words."""
    robot, held, why = search.robot, search.held, ""
    missed = [s for s in search.samples if s.violations]
    if search.best is not None:
        kind, values, q = (
            "whole-cycle improved start",
            search.best.values,
            search.best_motion.q[0, 0],
        )
    elif missed:
        closest = min(missed, key=lambda s: max(v.excess for v in s.violations))
        kind, values = "closest start", closest.values
        q = search.start_configuration(closest)
        why = f": no start keeps every stroke over the cycle; closest: {search.closest_violation}"
    else:
        kind, why = "default start", ": no start reaches the cycle"
        values, q = default_start(robot, search.segment, held)
    return kind, q, f"{kind} {named_values(robot, held, values)}{why}"


class Cost(NamedTuple):
    """A strategy's first cycle: the peak (or integral) of the objective, the peak ẋᵀẋ (m²/s²),
    the largest tracking error (m, and rad), whether it kept every checked limit and, with
    hydraulics, the pump energies under load sensing and constant pressure (kJ) and the limits of
    the circuit and of the cylinders' accelerations it passes (`circuit_violations`)."""

    objective: float
    peak_velocity_norm: float
    max_tracking_error: float
    within_limits: bool
    ls_energy_kj: float | None = None
    cp_energy_kj: float | None = None
    circuit_violations: tuple[Violation, ...] | None = None

    def figures(self) -> dict:
        """The cost as the report gives it (the energies and the circuit's limits passed, in
        words, only with hydraulics)."""
        figures = {k: v for k, v in self._asdict().items() if v is not None}
        if self.circuit_violations is not None:
            figures["circuit_violations"] = [str(v) for v in self.circuit_violations]
        return figures


def circuit_violations(cycle: WorkCycle, motion: Trajectory) -> list[Violation]:
    """Every interval over which the first motion of ``motion``, one whole ``cycle``, passes a
    limit of the circuit or a cylinder's acceleration limit, at its samples, in order of time
    (t in the cycle's time). The circuit's limits are the per-segment study's check
    (`Trajectory.hydraulic_violations`): each load pressure p_L at most what the machine's
    supply serves (relief − Δp_LS under LS, p_S under CP), the pump flow Q_P = Σ Q at most its
    maximum, each cylinder's speed |ẋ| at most its maximum. The accelerations' are
    −a_max ≤ ẍ ≤ a_max (`Limits.accelerations`), with ẍ = dẋ/dt by differences of the
    motion's own samples, through the corners where the path asks no step of ẋ
    (`cycle_accelerations`)."""
    x_ddot = cycle_accelerations(cycle, motion)[None]
    accelerations = Limits.accelerations(motion.robot).violations(motion.t[:1], x_ddot)
    return sorted(motion.hydraulic_violations(0) + accelerations[0], key=lambda v: v.start)


def cost(cycle: WorkCycle, motion: Trajectory, objective: Objective) -> Cost:
    """The `Cost` of the first motion of ``motion``, one whole ``cycle``."""
    hydraulic = motion.robot.hydraulics is not None
    return Cost(
        float(motion.score(objective)[0]),
        float(motion.peak_velocity_norm[0]),
        float(motion.max_tracking_error[0]),
        bool(motion.within_limits[0]),
        **(pump_energies(motion) if hydraulic else {}),
        circuit_violations=tuple(circuit_violations(cycle, motion)) if hydraulic else None,
    )


@dataclass(frozen=True, eq=False)
class CycleStudy:
    """One work cycle planned and repeated (module docstring). ``repetitions`` by strategy
    ("free", "periodic"); ``firsts`` each strategy's first cycle on the grid (for figures and
    playback) and ``costs`` its `Cost`; ``free_start`` the start the free strategy ran from,
    in words, and ``free_kind`` which it is ("whole-cycle improved start", or where none keeps
    every stroke the "closest start", or the "default start" where no start was reached);
    ``failures`` why a strategy or the return map did not run."""

    robot: Robot = field(repr=False)
    cycle: WorkCycle
    objective: Objective
    cycles: int
    checked: tuple[str, ...]
    circuit: bool
    plan: CyclePlan = field(repr=False)
    repetitions: dict[str, Repetition] = field(repr=False)
    firsts: dict[str, Trajectory] = field(repr=False)
    costs: dict[str, Cost]
    periodic: PeriodicOptimum | None = field(repr=False)
    map: ReturnMap | None = field(repr=False)
    free_start: str = "whole-cycle improved start"
    free_kind: str = "whole-cycle improved start"
    failures: dict[str, str] = field(default_factory=dict)

    @property
    def held(self) -> tuple[str, ...]:
        return self.plan.held

    @property
    def names(self) -> dict[str, str]:
        """Each strategy's name, the free one's with the start it really ran from."""
        return {"free": f"free, {self.free_kind}", "periodic": "periodic optimum (drift-free)"}

    def fixed_points(self, strategy: str) -> list[FixedPoint]:
        """The return map's fixed points where ``strategy`` is the law the map samples (the
        free one), else none: the free repetition settles only towards one of them."""
        return self.map.fixed_points if strategy == "free" and self.map is not None else []

    def price(self) -> dict | None:
        """The drift-free strategy against the free improved cycle, per cent (+: costs more)."""
        if not {"free", "periodic"} <= set(self.costs):
            return None
        free, periodic = self.costs["free"].figures(), self.costs["periodic"].figures()
        keys = [k for k in ("objective", "ls_energy_kj", "cp_energy_kj") if k in free]
        return {k: 100 * (periodic[k] / free[k] - 1) for k in keys}

    def report(self) -> dict:
        """The cycle study as JSON-ready data."""
        plan = self.plan
        return {
            **report_header(self.robot, self.cycle, self.checked, self.circuit),
            "objective": self.objective.name,
            "measure": self.objective.value_label,
            "unit": self.objective.value_unit(self.robot.actuators),
            "held_actuator": self.held[0] if len(self.held) == 1 else list(self.held),
            "cycles": self.cycles,
            "duration_s": self.cycle.duration,
            "segments": [
                {"name": s.name, "start": s.start.tolist(), "end": s.end.tolist(), **s.describe()}
                for s in self.cycle.segments
            ],
            "whole_cycle": search_report(plan.search),
            "per_segment": {
                "segments": [
                    {"name": s.segment.name, "best": best_report(s)} for s in plan.segments
                ],
                "corners": [corner_report(c) for c in plan.corners],
                "self_motion_time_s": plan.gap_time,
            },
            "strategies": {
                name: {
                    "name": self.names[name],
                    **self.costs[name].figures(),
                    "repetition": repetition_report(
                        self.repetitions[name], self.fixed_points(name)
                    ),
                }
                for name in self.repetitions
            },
            "free_start": self.free_start,
            "periodic": None
            if self.periodic is None
            else {
                "plan_peak": self.periodic.peak,
                "start_value": scalar_or_list(np.atleast_1d(self.periodic.r[0])),
                "change": self.periodic.change,
                "converged": self.periodic.converged,
                "failure": self.periodic.failure,
                "grids": [g.intervals for g in self.periodic.grids],
            },
            "periodic_versus_free_percent": self.price(),
            "return_map": None if self.map is None else map_report(self.map),
            "failures": self.failures,
        }


def report_header(robot: Robot, cycle: WorkCycle, checked: tuple[str, ...], circuit: bool) -> dict:
    """What a study's and a cycle study's reports open with: the robot, the task, the
    actuators whose limits count, each actuator's SI unit."""
    return {
        "robot": robot.name,
        "payload": robot.payload,
        "task": cycle.name,
        "checked_actuators": list(checked),
        "units": {a.name: a.unit for a in robot.actuators},
        "circuit_limits_checked": circuit,
    }


def best_report(search: SearchResult) -> dict | None:
    """A search's best start, its held values, every actuator's stroke and every joint's value
    there (m, or rad for an angle: the configuration, which the held values alone do not name
    where an arm's two elbows reach the start) and their peak, as JSON-ready data (None where
    no start is feasible)."""
    if search.best is None:
        return None
    robot, start = search.robot, search.best_motion
    return {
        "value": scalar_or_list(search.best.values),
        "strokes": dict(zip(robot.actuators.names, start.x[0, 0].tolist())),
        "joints": dict(zip(robot.joint_names, start.q[0, 0].tolist())),
        "peak": search.best_peak,
    }


def search_report(search: SearchResult, violations: SearchResult | None = None) -> dict:
    """A search as JSON-ready data: the held values' feasible range, the best start, the closest
    violation where no start is feasible (of ``violations``, by default of the search) and the
    simulations it ran."""
    box, closest = search.feasible_box, None
    if search.best is None:
        closest = (violations or search).closest_violation
    return {
        "feasible_range": None if box is None else (box[0] if len(box) == 1 else box).tolist(),
        "best": best_report(search),
        "closest_violation": None if closest is None else str(closest),
        "simulations": search.simulations,
    }


def corner_report(corner: Corner) -> dict:
    """A corner of the per-segment plan as JSON-ready data."""
    delta, held = corner.delta, corner.held_delta
    return {
        "after": corner.after,
        "before": corner.before,
        "point": corner.point.tolist(),
        "held_delta": None if held is None else dict(zip(corner.held, held.tolist())),
        "delta": None if delta is None else dict(zip(corner.names, delta.tolist())),
        "speed": corner.speed,
        "time_s": corner.time,
        "self_motion_within_limits": corner.within_limits,
        "reason": corner.reason,
    }


def repetition_report(repetition: Repetition, fixed_points: Sequence[FixedPoint] = ()) -> dict:
    """A repetition's drift, limits and settling (towards one of the return map's
    ``fixed_points``, `Repetition.settling_with`) as JSON-ready data."""
    first, drift = repetition.first_violation, repetition.drift
    settled = repetition.settling_with(fixed_points)
    held = repetition.held_values
    return {
        "strategy": repetition.strategy,
        "cycles": repetition.cycles,
        "held_values": (held[:, 0] if held.shape[1] == 1 else held).tolist(),
        "drift_per_cycle": {
            name: drift[:, j].tolist() for j, name in enumerate(repetition.robot.actuators.names)
        },
        "largest_drift_per_cycle": np.abs(drift).max(axis=1).tolist(),
        "tool_drift_per_cycle": repetition.tool_drift.tolist(),
        "within_limits_per_cycle": repetition.within.tolist(),
        "first_cycle_past_a_limit": None if first is None else first[0],
        "first_violation": None if first is None else first[1],
        "settling": settling_words(repetition, fixed_points),
        "settles": settled.settles,
        "limit_cycle_value": settled.limit,
        "contraction": settled.contraction,
    }


def settling_words(repetition: Repetition, fixed_points: Sequence[FixedPoint] = ()) -> str:
    """Whether the held actuator settles to a limit cycle (one of the return map's stable
    ``fixed_points``), in words: the limit cycle as the tables show the first held actuator's
    values (mm, degrees), the drift threshold in each actuator's SI unit."""
    settled, actuators = repetition.settling_with(fixed_points), repetition.robot.actuators
    if settled.settled_at is not None:
        units = " or ".join(sorted({a.unit for a in actuators}))
        return f"closed (drift below {SETTLED:g} {units}) from cycle {settled.settled_at}"
    ratio = (
        "" if settled.contraction is None else f"drift ratio {settled.contraction:.3g} per cycle"
    )
    if settled.settles and settled.limit is not None:  # settling towards that fixed point
        limit = amount(settled.limit, actuators[repetition.held[0]].unit)
        return (
            f"converging to the return map's stable limit cycle at {limit} "
            f"({ratio + ', ' if ratio else ''}closed in about {settled.cycles_to_settle} more "
            "cycles)"
        )
    return f"not settling after {repetition.cycles} cycles" + (f" ({ratio})" if ratio else "")


def map_report(mapped: ReturnMap) -> dict:
    """The return map as JSON-ready data."""
    return {
        "held_actuator": mapped.held,
        "values": mapped.values.tolist(),
        "next": [None if not np.isfinite(p) else float(p) for p in mapped.following],
        "within_limits": mapped.within.tolist(),
        "fixed_points": [{**p._asdict(), "stable": p.stable} for p in mapped.fixed_points],
        "identity": mapped.identity,
    }


@contextlib.contextmanager
def noted(failures: dict[str, str], key: str) -> Iterator[None]:
    """A part of a study that fails in the block for its input (a bound that does not solve, a
    task it cannot follow) does not stop the study: why is noted in ``failures[key]``."""
    try:
        yield
    except (InvalidInputError, UnreachableError) as error:
        failures[key] = str(error)


def run_cycle(
    robot: Robot,
    cycle: WorkCycle,
    objective: Objective = VELOCITY,
    cycles: int = CYCLES,
    strategy: str = "both",
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    method: str | None = None,
    circuit: bool = False,
    speed: float | None = None,
    progress: bool = False,
    segments: Sequence[SearchResult] | None = None,
) -> CycleStudy:
    """Plan ``cycle`` and run ``strategy`` ("free", "periodic" or "both") for ``cycles`` cycles
    (module docstring). ``speed`` is the held actuator's in the corners' self-motions (default
    `redundancy.planning.cycles.gap_speed`), ``segments`` the per-segment plan's searches where
    they were made already (`plan_cycle`); the other options as `run_study`'s."""
    require_robot(robot)
    from tqdm import tqdm

    if strategy not in CHOICES:
        raise InvalidInputError(f"unknown strategy {strategy!r}; strategies: {', '.join(CHOICES)}")
    cycles = checked_cycles(cycles)
    cycle.check_continuous(closed=True)
    objective = as_objective(objective)
    if strategy == "periodic" and objective.reduction != "peak":
        raise InvalidInputError(
            f"the periodic strategy minimises a peak; objective {objective.name!r} reduces its "
            f"measure by {objective.reduction!r}: run the free strategy (--strategy free), or "
            "a peak objective"
        )
    chosen = STRATEGIES if strategy == "both" else (strategy,)
    failures: dict[str, str] = {}
    if strategy == "both" and objective.reduction != "peak":  # it minimises a peak only
        chosen = ("free",)
        failures["periodic"] = (
            f"the periodic optimum minimises a peak; objective {objective.name!r} reduces its "
            f"measure by {objective.reduction!r}: only the free strategy runs"
        )
    held = held_actuators(robot, cycle)
    if circuit:
        robot.circuit()  # says how to declare one before any work
    steps = 2 + 2 * len(chosen)
    bar = tqdm(total=steps, unit="step", desc="cycle", disable=not progress, mininterval=0.5)
    with bar:
        bar.set_description("cycle: plan")
        plan = plan_cycle(
            robot, cycle, objective, held, samples, checked, method, circuit, speed, segments
        )
        bar.update()
        free_motion = plan.motion
        free_kind, start_q, free_start = free_start_of(plan.search)
        repetitions: dict[str, Repetition] = {}
        firsts: dict[str, Trajectory] = {}
        periodic = None

        def repeated(strategy: str, laws, start: np.ndarray) -> None:
            """Run ``strategy``'s ``laws`` from ``start`` for ``cycles`` cycles; keep its first."""
            repetitions[strategy] = repeat(
                robot, cycle, laws, start, cycles, strategy, held, checked, circuit, objective
            )
            firsts[strategy] = repetitions[strategy].motion(1)

        settled: list[Repetition] = []  # the free cycles, where a strategy reads where they end

        def free_cycles() -> Repetition:
            """The free strategy's repetition: run here, once, where it was not asked for."""
            if "free" in repetitions:
                return repetitions["free"]
            if not settled:
                settled.append(
                    repeat(robot, cycle, objective.resolver, start_q, cycles, "free", held, checked)
                )
            return settled[0]

        if "free" in chosen:
            bar.set_description("cycle: free, repeated")
            repeated("free", objective.resolver, start_q)
            bar.update(2)
        if "periodic" in chosen:
            bar.set_description("cycle: periodic optimum")
            guess = free_motion if free_motion is not None else firsts.get("free")
            if guess is None:
                guess = repeat(
                    robot, cycle, objective.resolver, start_q, 1, "free", held, checked
                ).motion(1)
            with noted(failures, "periodic"):
                try:
                    periodic = periodic_optimum(robot, cycle, guess, objective, held, checked)
                except InvalidInputError:
                    # a plan's cycle that changes assembly branch (an arm flipping its elbow as
                    # it slews around its base) has no periodic motion near it; the free
                    # repetition's last cycle runs on the branch the cycles settle on
                    last = free_cycles().motion(cycles)
                    periodic = periodic_optimum(robot, cycle, last, objective, held, checked)
            bar.update()
            if periodic is not None:
                bar.set_description("cycle: periodic, repeated")
                repeated("periodic", periodic.laws(), periodic.start)
            bar.update()
        bar.set_description("cycle: return map")
        mapped = None
        # the map follows the branch the free cycles run on
        free = repetitions.get("free") or (settled[0] if settled else None)
        near = None if free is None else free.motions[-1].q[0, -1]
        with noted(failures, "return map"):
            mapped = return_map(robot, cycle, objective.resolver, held, checked=checked, near=near)
    return CycleStudy(
        robot,
        cycle,
        objective,
        cycles,
        tuple(robot.actuators.names if checked is None else checked),
        circuit,
        plan,
        repetitions,
        firsts,
        {name: cost(cycle, motion, objective) for name, motion in firsts.items()},
        periodic,
        mapped,
        free_start,
        free_kind,
        failures,
    )
