"""The work cycle as a machine runs it, as one report: `redundancy cycle` and the study's cycle
section.

For one objective (a peak one for the drift-free strategy):

- the plan (`redundancy.planning.cycles.plan_cycle`): the improved start over the whole cycle,
  and beside it the paper's per-segment plan with the self-motion each corner would need;
- the strategies, each run for ``cycles`` cycles one after another (`repeat`):
  "free", the objective's law from the whole-cycle improved start (the default start where no
  start keeps the strokes), which drifts; and "periodic", the drift-free periodic optimum
  (`periodic_optimum`), run by the law that follows its plan;
- the drift of every actuator and of the tool per cycle, the first cycle that passes a stroke,
  whether the free cycle settles to a limit cycle, and the return map of the held actuator at
  the cycle's start whose fixed points are those limit cycles;
- the drift-free strategy's cost against the free improved cycle: the peak of the objective and,
  with hydraulics, the pump energy under load sensing and constant pressure
  (`Trajectory.energy`), over the first cycle.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.model.hydraulics import KILOJOULE
from redundancy.model.robot import Robot
from redundancy.planning.cycles import (
    CYCLES,
    CycleMotion,
    CyclePlan,
    PeriodicOptimum,
    Repetition,
    ReturnMap,
    default_cycle_start,
    periodic_optimum,
    plan_cycle,
    repeat,
    return_map,
)
from redundancy.planning.starts import held_actuators, scalar_or_list
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import VELOCITY, Objective
from redundancy.study.output import write_atomically

STRATEGIES = ("free", "periodic")
CHOICES = (*STRATEGIES, "both")
NAMES = {
    "free": "free, whole-cycle improved start",
    "periodic": "periodic optimum (drift-free)",
}


@dataclass(frozen=True, eq=False)
class CycleStudy:
    """One work cycle planned and repeated (module docstring). ``repetitions`` by strategy
    ("free", "periodic"); ``firsts`` each strategy's first cycle on the grid (for its cost,
    figures and playback); ``failures`` why a strategy or the return map did not run."""

    robot: Robot = field(repr=False)
    cycle: WorkCycle
    objective: Objective
    cycles: int
    checked: tuple[str, ...]
    circuit: bool
    plan: CyclePlan = field(repr=False)
    repetitions: dict[str, Repetition] = field(repr=False)
    firsts: dict[str, CycleMotion] = field(repr=False)
    periodic: PeriodicOptimum | None = field(repr=False)
    map: ReturnMap | None = field(repr=False)
    free_start: str = "whole-cycle improved start"
    failures: dict[str, str] = field(default_factory=dict)

    @property
    def held(self) -> tuple[str, ...]:
        return self.plan.held

    def cost(self, strategy: str) -> dict:
        """A strategy's first cycle: the peak (or integral) of the objective, the peak ẋᵀẋ, the
        largest tracking error and, with hydraulics, the pump energies in kJ."""
        motion = self.firsts[strategy]
        found = {
            "objective": float(motion.score(self.objective)[0]),
            "peak_velocity_norm": float(motion.peak_velocity_norm[0]),
            "max_tracking_error": float(motion.max_tracking_error[0]),
            "within_limits": bool(motion.within_limits[0]),
        }
        if self.robot.hydraulics is not None:
            circuit = self.robot.hydraulics
            found["ls_energy_kj"] = float(motion.energy(circuit.load_sensing)[0] / KILOJOULE)
            found["cp_energy_kj"] = float(motion.energy(circuit.constant_pressure)[0] / KILOJOULE)
        return found

    def price(self) -> dict | None:
        """The drift-free strategy against the free improved cycle, per cent (+: costs more)."""
        if not {"free", "periodic"} <= set(self.firsts):
            return None
        free, periodic = self.cost("free"), self.cost("periodic")
        keys = [k for k in ("objective", "ls_energy_kj", "cp_energy_kj") if k in free]
        return {k: 100 * (periodic[k] / free[k] - 1) for k in keys}

    def report(self) -> dict:
        """The cycle study as JSON-ready data."""
        plan, search = self.plan, self.plan.search
        best = search.best
        box = search.feasible_box
        closest = search.closest_violation if best is None else None
        return {
            "robot": self.robot.name,
            "payload": self.robot.payload,
            "task": self.cycle.name,
            "objective": self.objective.name,
            "measure": self.objective.label,
            "held_actuator": self.held[0] if len(self.held) == 1 else list(self.held),
            "checked_actuators": list(self.checked),
            "circuit_limits_checked": self.circuit,
            "cycles": self.cycles,
            "duration_s": self.cycle.duration,
            "segments": [
                {"name": s.name, "start": s.start.tolist(), "end": s.end.tolist(), **s.describe()}
                for s in self.cycle.segments
            ],
            "whole_cycle": {
                "feasible_range": None
                if box is None
                else (box[0] if len(box) == 1 else box).tolist(),
                "best": None
                if best is None
                else {"value": scalar_or_list(best.values), "peak": search.best_peak},
                "closest_violation": None if closest is None else str(closest),
                "simulations": search.simulations,
            },
            "per_segment": {
                "segments": [
                    {
                        "name": s.segment.name,
                        "best": None
                        if s.best is None
                        else {"value": scalar_or_list(s.best.values), "peak": s.best_peak},
                    }
                    for s in plan.segments
                ],
                "corners": [c.report() for c in plan.corners],
                "self_motion_time_s": plan.gap_time,
            },
            "strategies": {
                name: {
                    "name": NAMES[name],
                    **self.cost(name),
                    "repetition": self.repetitions[name].report(),
                }
                for name in self.repetitions
            },
            "free_start": self.free_start,
            "periodic": None
            if self.periodic is None
            else {
                "plan_peak": self.periodic.peak,
                "start_value": float(self.periodic.r[0]),
                "change": self.periodic.change,
                "converged": self.periodic.converged,
                "grids": [g.intervals for g in self.periodic.grids],
            },
            "periodic_versus_free_percent": self.price(),
            "return_map": None if self.map is None else self.map.report(),
            "failures": self.failures,
        }

    def table(self) -> str:
        """The cycle study as text: the plan, the corners, the repetitions, the price."""
        plan, held = self.plan, self.held
        unit = self.objective.unit
        label = self.objective.label
        route = " → ".join(s.name for s in self.cycle.segments)
        lines = [
            f"work cycle {self.cycle.name!r}: {route} ({self.cycle.duration:.2f} s), "
            f"{self.objective.name} objective, held {', '.join(held)}"
        ]
        search = plan.search
        if search.best is None:
            closest = search.closest_violation
            lines.append(
                "whole-cycle improved start: none keeps every stroke over the cycle"
                + (f"; closest: {closest}" if closest else "")
            )
        else:
            box = search.feasible_box
            span = ", ".join(f"[{lo:.4g}, {hi:.4g}]" for lo, hi in box)  # type: ignore[union-attr]
            lines.append(
                f"whole-cycle improved start: {_values(held, search.best.values)} "
                f"(feasible {span}), peak {label} {search.best_peak:.5g} {unit} "
                f"({search.simulations} motions)"
            )
        starts = [
            "none" if s.best is None else _values(held, s.best.values, names=False)
            for s in plan.segments
        ]
        peaks = [peak for s in plan.segments if (peak := s.best_peak) is not None]
        lines.append(
            f"per-segment plan: best starts {' / '.join(starts)}"
            + (f", peak {label} {max(peaks):.5g} {unit}" if peaks else "")
            + ", with a self-motion at every corner:"
        )
        names = list(self.robot.actuators.names)
        header = f"  {'corner':<18}" + "".join(f"{'Δ' + n:>10}" for n in names)
        header += f"{'time s':>9}  self-motion"
        lines += [header]
        for corner in plan.corners:
            delta = corner.delta
            row = f"  {corner.after + ' → ' + corner.before:<18}"
            if delta is None:
                lines.append(row + f"  {corner.reason}")
                continue
            row += "".join(f"{d:>10.4f}" for d in delta)
            state = {True: "keeps the strokes", False: "passes a stroke", None: "-"}
            reason = corner.reason or state[corner.within_limits]
            lines.append(row + f"{corner.time:>9.2f}  {reason}")
        if plan.gap_time is not None and plan.corners:
            lines.append(
                f"  the self-motions add {plan.gap_time:.2f} s per cycle, the held actuator at "
                f"{plan.corners[0].speed:g} m/s"
            )
        lines += ["", self._repetition_table()]
        price = self.price()
        if price is not None:
            free, periodic = self.cost("free"), self.cost("periodic")
            parts = [
                f"peak {label} {free['objective']:.5g} → {periodic['objective']:.5g} {unit} "
                f"({price['objective']:+.1f} %)"
            ]
            for key, name in (("ls_energy_kj", "LS"), ("cp_energy_kj", "CP")):
                if key in price:
                    parts.append(
                        f"{name} pump energy {free[key]:.2f} → {periodic[key]:.2f} kJ "
                        f"({price[key]:+.1f} %)"
                    )
            lines.append("drift-free against the free improved cycle: " + "; ".join(parts))
        if self.map is not None:
            lines.append(
                f"return map of {self.map.held} at the cycle's start: {self.map.describe()}"
            )
        for name, reason in self.failures.items():
            lines.append(f"{name}: {reason}")
        return "\n".join(lines)

    def _repetition_table(self) -> str:
        header = (
            f"{'strategy':<34}{'cycles':>7}{'drift/cycle: first':>20}{'last':>11}"
            f"{'tool drift':>12}  first stroke passed; settling"
        )
        lines = [header, "-" * len(header)]
        for name, repetition in self.repetitions.items():
            largest = np.abs(repetition.drift).max(axis=1)
            first = repetition.first_violation
            passed = "none" if first is None else f"cycle {first[0]}: {first[1]}"
            lines.append(
                f"{NAMES[name]:<34}{repetition.cycles:>7}{largest[0]:>20.3g}{largest[-1]:>11.3g}"
                f"{repetition.tool_drift.max():>12.3g}  {passed}; {repetition.settling}"
            )
        return "\n".join(lines)


def _values(held, values, names: bool = True) -> str:
    if names:
        return ", ".join(f"{h} = {v:.4g}" for h, v in zip(held, values))
    return ",".join(f"{v:.4g}" for v in values)


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
) -> CycleStudy:
    """Plan ``cycle`` and run ``strategy`` ("free", "periodic" or "both") for ``cycles`` cycles
    (module docstring). ``speed`` is the held actuator's in the corners' self-motions (default
    `redundancy.planning.cycles.gap_speed`); the other options as `run_study`'s."""
    from tqdm import tqdm

    if strategy not in CHOICES:
        raise InvalidInputError(f"unknown strategy {strategy!r}; strategies: {', '.join(CHOICES)}")
    if not isinstance(cycles, int | np.integer) or not 1 <= cycles <= 10_000:
        raise InvalidInputError(f"cycles must be a whole number within [1, 10,000]; got {cycles!r}")
    cycle.check_continuous(closed=True)
    chosen = STRATEGIES if strategy == "both" else (strategy,)
    held = held_actuators(robot, cycle)
    if chosen == ("periodic",) and len(held) != 1:
        raise InvalidInputError(
            f"the periodic strategy holds one actuator; {robot.name}'s task holds {list(held)}: "
            "run the free strategy (--strategy free)"
        )
    if circuit:
        robot.circuit()  # says how to declare one before any work
    steps = 2 + 2 * len(chosen)
    bar = tqdm(total=steps, unit="step", desc="cycle", disable=not progress, mininterval=0.5)
    failures: dict[str, str] = {}
    with bar:
        bar.set_description("cycle: plan")
        plan = plan_cycle(robot, cycle, objective, held, samples, checked, method, circuit, speed)
        bar.update()
        free_start = "whole-cycle improved start"
        free_motion = plan.motion
        if free_motion is not None:
            start_q = free_motion.start[0]
        else:
            values, start_q = default_cycle_start(robot, cycle, held)
            free_start = f"default start {_values(held, values)}: no start keeps every stroke"
        repetitions: dict[str, Repetition] = {}
        firsts: dict[str, CycleMotion] = {}
        periodic = None
        if "free" in chosen:
            bar.set_description("cycle: free, repeated")
            repetitions["free"] = repeat(
                robot,
                cycle,
                objective.resolver,
                start_q,
                cycles,
                "free",
                held,
                checked,
                circuit,
                objective,
            )
            bar.update()
            firsts["free"] = repetitions["free"].motion(1)
            bar.update()
        if "periodic" in chosen:
            bar.set_description("cycle: periodic optimum")
            guess = free_motion if free_motion is not None else firsts.get("free")
            if guess is None:
                guess = repeat(
                    robot, cycle, objective.resolver, start_q, 1, "free", held, checked
                ).motion(1)
            try:
                if len(held) != 1:
                    raise InvalidInputError(
                        f"the periodic optimum holds one actuator; the task holds {list(held)}"
                    )
                periodic = periodic_optimum(robot, cycle, guess, objective, held[0], checked)
            except (InvalidInputError, UnreachableError) as error:
                failures["periodic"] = str(error)
            bar.update()
            if periodic is not None:
                bar.set_description("cycle: periodic, repeated")
                repetitions["periodic"] = repeat(
                    robot,
                    cycle,
                    periodic.laws(),
                    periodic.start,
                    cycles,
                    "periodic",
                    held,
                    checked,
                    circuit,
                    objective,
                )
                firsts["periodic"] = repetitions["periodic"].motion(1)
            bar.update()
        bar.set_description("cycle: return map")
        mapped = None
        if len(held) == 1:
            try:
                mapped = return_map(robot, cycle, objective.resolver, held[0], checked=checked)
            except (InvalidInputError, UnreachableError) as error:
                failures["return map"] = str(error)
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
        periodic,
        mapped,
        free_start,
        failures,
    )


def write_cycle_report(study: CycleStudy, path: Path) -> None:
    """The cycle study's JSON report, written atomically."""
    text = json.dumps(study.report(), indent=1, allow_nan=False)
    write_atomically(path, lambda p: p.write_text(text + "\n"))
