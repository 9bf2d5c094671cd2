"""The study's and the cycle study's results as fixed-width text tables.

Tables read finished numbers only: every figure they show was computed by the run that made the
result (`run_study`, `run_cycle`), so printing one evaluates no state.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from redundancy.model.hydraulics import BAR, BEYOND_RELIEF, KILOJOULE, SUPPLIES
from redundancy.planning.cycles import ROUNDING, SETTLED, ReturnMap
from redundancy.planning.ik import named_values
from redundancy.resolution.limits import amount
from redundancy.resolution.objectives import VELOCITY
from redundancy.study.check import Check, span
from redundancy.study.cycles import CycleStudy, settling_words
from redundancy.study.study import Study

RUN_COLUMNS = {"segment": "<", "strategy": "<"}  # the first columns of a table of runs
HYDRAULIC_COLUMNS = dict.fromkeys(
    ["Q_P L/min", "p_L bar", "LS kJ", "CP kJ", "LS +%", "CP +%", "t_min s"], ">"
)


def text_table(columns: dict[str, str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A fixed-width table ruled under its header: ``columns`` maps each column's name (with its
    unit) to its alignment, "<" or ">"; each row holds one formatted cell per column. Each column
    is as wide as its widest cell, two spaces apart; trailing blanks are cut."""
    table = [list(columns), *rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(columns))]
    aligned = [
        "  ".join(f"{cell:{a}{w}}" for cell, a, w in zip(row, columns.values(), widths)).rstrip()
        for row in table
    ]
    return [aligned[0], "-" * len(aligned[0]), *aligned[1:]]


def study_table(study: Study) -> str:
    """The comparison (held starts in mm, or degrees for a rotary actuator), then the bounds,
    the hydraulic comparison where the robot has a circuit, and the cycle section."""
    actuators = study.robot.actuators
    units = [actuators[h].unit for h in study.held]
    rows = []
    for run in study.runs:
        row = run.summary()
        # a limit passed is named: the first violation (in time), the count of the others
        passed = row["violations"]
        held = "kept" if row["within_limits"] else f"passed: {passed[0]}" if passed else "failed"
        more = f" (+{len(passed) - 1} more)" if len(passed) > 1 else ""
        kinetic = "-" if row["peak_kinetic"] is None else f"{row['peak_kinetic']:.3f}"
        values = ",".join(amount(v, unit) for v, unit in zip(run.start, units))
        peak = f"{row['peak_velocity_norm']:.5f}"
        rows.append([run.segment, run.strategy, values, peak, kinetic, held + more])
    squared = VELOCITY.unit_of(actuators)
    start = "start " + ",".join(study.held)
    columns = dict.fromkeys([start, f"peak ẋᵀẋ {squared}", "peak ẋᵀM_Hẋ J"], ">")
    limits = "strokes, circuit" if study.circuit else "strokes"  # what the column checks
    lines = text_table(RUN_COLUMNS | columns | {limits: "<"}, rows)
    bounds = []
    for name, searches in study.searches.items():
        unit = searches[0].objective.value_unit(actuators)
        for search in searches:
            segment = search.segment.name
            head = [segment, name, unit]
            if search.best is None:
                closest = study.sweep(name, segment).closest_violation
                words = "no sampled start stays inside the limits"
                words += f"; closest: {closest}" if closest else ""
                bounds.append([*head, "none", "-", "-", words])
                continue
            bound, failure = study.result(name, segment), study.withheld(name, segment)
            cells = ["", "", ""]  # a withheld bound is named with its reason
            if failure is not None:
                cells = ["-", "-", f"no bound: {failure}"]
            elif bound is not None:
                cells = [f"{bound.bound:.5g}", f"{study.gap(name, segment):z.2f}", ""]
            bounds.append([*head, f"{search.best_peak:.5g}", *cells])
    columns = {"segment": "<", "objective": "<", "unit": "<", "improved": ">", "bound": ">"}
    lines += ["", *text_table(columns | {"gap %": ">", "": "<"}, bounds)]
    if study.robot.hydraulics is not None:
        lines += ["", hydraulic_table(study)]
    if study.cycle_study is not None:
        lines += ["", cycle_table(study.cycle_study)]
    elif study.cycle_skipped:
        lines += ["", f"no cycle section: {study.cycle_skipped}"]
    return "\n".join(lines)


def hydraulic_table(study: Study) -> str:
    """The hydraulic comparison: peak pump flow, highest load pressure, pump energies, shortest
    duration and, with energy bounds, per cent above them, then the bounds."""
    circuit = study.robot.circuit()
    bounded = bool(study.energy_bounds)  # without energy bounds, no columns of dashes for them
    rows = []
    for run in study.runs:
        figures, above = run.summary()["hydraulics"], study.above_energy_bound(run)
        shortest, pressure = figures["shortest_duration_s"], figures["max_load_pressure_bar"]
        unphysical = circuit.unphysical(pressure * BAR)
        # a supply that cannot serve the load pressure: its energy is a pump's past its relief
        unserved = list(SUPPLIES) if unphysical else figures["unserved"]
        note = ""
        if unphysical:
            note = (
                f"(!) p_L {pressure:.0f} bar, over {BEYOND_RELIEF:g} × the relief "
                f"{circuit.relief / BAR:g} bar: no circuit delivers it (a cylinder too small "
                "for its load, or the model's forces past a stroke or a linkage's dead centre); "
            )
        elif unserved:
            served = " and ".join(f"{s} ({_served(circuit, s):g} bar)" for s in unserved)
            verb = "serves" if len(unserved) == 1 else "serve"
            note = f"(!) p_L {pressure:.1f} bar, past what {served} {verb}: no energy; "
        energies = [
            "(!)" if s in unserved else f"{figures[f'{s.lower()}_energy_kj']:.2f}" for s in SUPPLIES
        ]
        rows.append(
            [
                run.segment,
                run.strategy,
                f"{figures['peak_pump_flow_l_min']:.1f}",
                "(!)" if unphysical else f"{pressure:.1f}",
                *energies,
                *(  # per cent above a bound, of energies not shown: not shown either
                    f"{above[s]:.1f}" if s in above and s not in unserved else "-"
                    for s in (SUPPLIES if bounded else ())
                ),
                "-" if shortest is None else f"{shortest:.2f}",
                note
                + (
                    ""
                    if shortest is not None
                    else f"t_min: {figures['shortest_duration_reason']}; "
                )
                + ("kept" if figures["within_limits"] else "; ".join(figures["violations"])),
            ]
        )
    for segment in study.energy_bounds or {}:
        for supply in SUPPLIES:  # a bound whose solve raised is named with its reason too
            failure = study.energy_withheld(segment, supply)
            bound = study.energy_result(segment, supply)
            energy = "-" if bound is None else f"{bound.energy / KILOJOULE:.2f}"
            ls, cp = (energy, "") if supply == "LS" else ("", energy)
            note = "" if failure is None else f"no bound: {failure}"
            rows.append([segment, f"energy bound, {supply}", "", "", ls, cp, "", "", "", note])
    columns = {k: v for k, v in HYDRAULIC_COLUMNS.items() if bounded or not k.endswith("+%")}
    return "\n".join(text_table(RUN_COLUMNS | columns | {"circuit": "<"}, rows))


def _served(circuit, supply: str) -> float:
    """The highest load pressure ``supply`` (its name) serves under the circuit's relief, bar."""
    found = next(s for s in circuit.supplies if s.name == supply)
    return found.available(circuit.relief) / BAR


def cycle_table(study: CycleStudy) -> str:
    """The cycle study: the plan, the corners, the repetitions, the price."""
    route = " → ".join(s.name for s in study.cycle.segments)
    lines = [
        f"work cycle {study.cycle.name!r}: {route} ({study.cycle.duration:.2f} s), "
        f"{study.objective.name} objective, held {', '.join(study.held)}",
        *_plan_lines(study),
        *_corner_lines(study),
        "",
        _repetition_table(study),
        *_circuit_lines(study),
    ]
    if study.price() is not None:
        lines.append(_price_line(study))
    if study.map is not None:
        words = fixed_point_words(study.map, study.robot.actuators[study.map.held].unit)
        lines.append(f"return map of {study.map.held} at the cycle's start: {words}")
    lines += [f"{name}: {reason}" for name, reason in study.failures.items()]
    return "\n".join(lines)


def _plan_lines(study: CycleStudy) -> list[str]:
    """The whole-cycle improved start and the per-segment plan's starts."""
    plan, held = study.plan, study.held
    objective = study.objective
    unit, label = objective.value_unit(study.robot.actuators), objective.value_label
    units = [study.robot.actuators[h].unit for h in held]
    search = plan.search
    if search.best is None:
        closest = search.closest_violation
        whole = "whole-cycle improved start: none keeps every stroke over the cycle" + (
            f"; closest: {closest}" if closest else ""
        )
    else:
        box = search.feasible_box  # a best start is feasible: there is a box
        ranges = ", ".join(span(lo, hi, u) for (lo, hi), u in zip(box, units))  # type: ignore[arg-type]
        whole = (
            f"whole-cycle improved start: {named_values(study.robot, held, search.best.values)} "
            f"(feasible {ranges}), {label} {search.best_peak:.5g} {unit} "
            f"({search.simulations} motions)"
        )
    starts = [
        "none" if s.best is None else ",".join(amount(v, u) for v, u in zip(s.best.values, units))
        for s in plan.segments
    ]
    whole_plan = objective.over_segments([s.best_peak for s in plan.segments])
    per_segment = (
        f"per-segment plan: best starts {' / '.join(starts)}"
        + ("" if whole_plan is None else f", {label} {whole_plan:.5g} {unit}")
        + ", with a self-motion at every corner:"
    )
    return [whole, per_segment]


def _corner_lines(study: CycleStudy) -> list[str]:
    """The self-motion of every corner of the per-segment plan, and the time they add."""
    plan, actuators = study.plan, study.robot.actuators
    state = {True: "keeps the strokes", False: "passes a stroke", None: "-"}
    rows = []
    for corner in plan.corners:
        name, delta = f"{corner.after} → {corner.before}", corner.delta
        if delta is None:
            rows.append([name, *[""] * (len(actuators.names) + 1), str(corner.reason)])
            continue
        shown = [amount(d, a.unit) for d, a in zip(delta, actuators)]
        words = corner.reason or state[corner.within_limits]
        rows.append([name, *shown, f"{corner.time:.2f}", words])
    columns = {"corner": "<"} | {f"Δ{n}": ">" for n in actuators.names}
    lines = [
        "  " + line for line in text_table(columns | {"time s": ">", "self-motion": "<"}, rows)
    ]
    if plan.gap_time is not None and plan.corners:
        lines.append(
            f"  the self-motions add {plan.gap_time:.2f} s per cycle, the held "
            f"{'actuator' if len(study.held) == 1 else 'actuators'} at "
            f"{plan.corners[0].speed:g} {actuators[study.held[0]].unit}/s"
        )
    return lines


def _price_line(study: CycleStudy) -> str:
    """The drift-free strategy's peak and pump energies against the free improved cycle's."""
    price, label = study.price() or {}, study.objective.value_label
    unit = study.objective.value_unit(study.robot.actuators)
    free, periodic = study.costs["free"].figures(), study.costs["periodic"].figures()
    parts = [
        f"{label} {free['objective']:.5g} → {periodic['objective']:.5g} {unit} "
        f"({price['objective']:+.1f} %)"
    ]
    for key, name in (("ls_energy_kj", "LS"), ("cp_energy_kj", "CP")):
        if key in price:
            parts.append(
                f"{name} pump energy {free[key]:.2f} → {periodic[key]:.2f} kJ ({price[key]:+.1f} %)"
            )
    line = "drift-free against the free improved cycle: " + "; ".join(parts)
    failure = study.periodic.failure if study.periodic is not None else None
    if failure is not None:  # the motions compare; the plan is not shown to be the optimum
        line += f" (the periodic plan is not shown optimal: {failure})"
    return line


def _circuit_lines(study: CycleStudy) -> list[str]:
    """Each strategy whose first cycle passes a limit of the circuit or of a cylinder's
    acceleration, with every limit it passes (its times in the cycle's); none where every
    strategy keeps them all."""
    return [
        f"{study.names[name]} passes the circuit's limits in its first cycle: "
        + "; ".join(str(v) for v in cost.circuit_violations)
        for name, cost in study.costs.items()
        if cost.circuit_violations
    ]


def _repetition_table(study: CycleStudy) -> str:
    actuators = study.robot.actuators

    def largest(drift: np.ndarray) -> str:  # of one cycle's, named: they differ in unit
        i = int(drift.argmax())
        if drift[i] < ROUNDING:  # none moved, to the integration's rounding: none to name
            return "0"
        return f"{amount(drift[i], actuators.maps[i].unit)} {actuators.maps[i].name}"

    rows = []
    for name, repetition in study.repetitions.items():
        drift = np.abs(repetition.drift)  # (cycles, n): each actuator's, in its own unit
        first_cycle, last_cycle = (largest(d) for d in drift[[0, -1]])
        first = repetition.first_violation
        passed = "none" if first is None else f"cycle {first[0]}: {first[1]}"
        settling = settling_words(repetition, study.fixed_points(name))
        tool = amount(repetition.tool_drift[-1], "m")
        cells = [str(repetition.cycles), first_cycle, last_cycle, tool, f"{passed}; {settling}"]
        rows.append([study.names[name], *cells])
    columns = dict.fromkeys(["cycles", "drift/cycle: first", "last", "tool drift: last"], ">")
    spec = {"strategy": "<"} | columns | {"first stroke passed; settling": "<"}
    return "\n".join(text_table(spec, rows))


def fixed_point_words(mapped: ReturnMap, unit: str) -> str:
    """The return map's limit cycles in words, the held actuator's values in ``unit`` (SI)."""
    found = mapped.fixed_points
    if not found and mapped.identity:
        return f"every start comes back to itself (within {SETTLED:g} {unit}): no drift to settle"
    if not found:
        return "no fixed point over the reachable stroke"
    return "; ".join(
        f"limit cycle at {amount(point.value, unit)} (P' = {point.slope:.3g}, "
        f"{'stable' if point.stable else 'unstable'}"
        + ("" if point.keeps_the_strokes else ", its cycle passes a stroke")
        + ")"
        for point in found
    )


def joint_lines(robot) -> list[str]:
    """The robot's joints and their ranges (mm, degrees), under a heading."""
    ranges = zip(robot.joint_names, robot.lower, robot.upper, robot.rotary_joints)
    return ["joints:"] + [
        f"  {name:<20} {span(lo, hi, 'rad' if rotary else 'm')}" for name, lo, hi, rotary in ranges
    ]


def check_table(found: Check) -> str:
    """The one-screen check of a robot: lengths in mm, angles in degrees."""
    robot = found.robot
    lines = [f"{robot.name}: n = {robot.n}, m = {robot.m} (task {robot.task_axes})"]
    lines += joint_lines(robot)
    lines.append("actuators (values over the joint's range against the stroke):")
    for a in found.actuators:
        unit = "rad" if a.rotary else "m"
        verdict = (
            "UNREACHABLE"
            if a.unreachable
            else ("MISMATCH: a stroke end is not reached" if a.mismatch else "ok")
        )
        lines.append(
            f"  {a.name:<8} on {a.joint:<18} reaches {span(*a.reached, unit)}, "
            f"stroke {span(*a.stroke, unit)}: {verdict}"
        )
        for value, x in zip(a.singular, a.singular_x):
            inside = a.stroke[0] <= x <= a.stroke[1]
            lines.append(
                f"    A singular at {a.joint} = {a.joint_value(value)} ({a.name} = "
                f"{amount(x, unit)}, {'inside' if inside else 'outside'} the stroke): "
                + a.why_singular
            )
        if a.undefined is not None:
            lines.append(f"    not defined {a.undefined_range}: {a.why_undefined}")
    if robot.kinematic_only:
        lines.append(
            f"masses: none on {', '.join(robot.massless_links)} (kinematic only: the "
            "velocity objective, play and check work; the energy objective refuses)"
        )
    else:
        total = sum(inertia.mass for inertia in robot.model.inertias[1:])  # not the ground's
        lines.append(
            f"masses: on every moving link, {total:.1f} kg in all, of which payload "
            f"{robot.payload:.1f} kg"
        )
    lines.append(
        "meshes: "
        + (
            f"not found: {', '.join(robot.missing_meshes)} (those links drawn as hulls)"
            if robot.missing_meshes
            else "every mesh found"
        )
    )
    if found.points is not None:
        lines.append("task points:")
        lines += [
            f"  {found.point(i)}: {'reached' if ok else 'NOT reached'}"
            for i, ok in enumerate(found.reached)
        ]
    problems = found.blocking()
    lines.append(
        "ready for a study"
        if not problems
        else ("1 problem blocks" if len(problems) == 1 else f"{len(problems)} problems block")
        + " a study: "
        + "; ".join(problems)
    )
    return "\n".join(lines)
