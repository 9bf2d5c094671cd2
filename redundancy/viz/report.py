"""index.html: one page that gathers what a command wrote into its output folder.

The page reads the folder's report (``report.json`` of `redundancy study` or `redundancy cycle`,
``summary.json`` of `redundancy map`) and the names of the files beside it, and computes
nothing: a summary first (what was solved, the headline numbers), then every table with its
units, every figure with a caption saying what it shows and what its encodings mean, every
playback linked, the hydraulics, and the work cycle with its drift. It loads nothing from the
network, so the folder can be copied and opened anywhere.
"""

from __future__ import annotations

import html
import json
from collections.abc import Iterable
from fnmatch import fnmatch
from pathlib import Path
from string import Template
from types import SimpleNamespace

from redundancy.planning.cycles import ROUNDING
from redundancy.resolution.objectives import OBJECTIVES, VELOCITY
from redundancy.study.output import write_atomically

# What each figure shows and how to read it, by file-name pattern; the first match captions it.
CAPTIONS = (
    (
        "fig4a_*",
        "The paper's Fig. 4a: the peak of ẋᵀẋ (m²/s²) along each segment's motion under the "
        "unweighted pseudoinverse, against the held actuator's initial value. One colour per "
        "segment; dotted: every reachable start of the sweep, solid with dots: those whose "
        "motion keeps every checked stroke; shaded: the feasible range whose ends the improved "
        "search located (the table's); ★ the improved start.",
    ),
    (
        "fig5a_*",
        "The paper's Fig. 5a: as Fig. 4a for the M_H-weighted pseudoinverse, the peak of "
        "ẋᵀ M_H ẋ, twice the kinetic energy (J). A segment with no feasible start has no solid "
        "curve and no ★; the legend says so.",
    ),
    (
        "fig*a_peak_*",
        "The objective (its peak, or its integral) against the held actuators' initial "
        "values: for one held actuator as Fig. 4a; for several, colour the objective, filled "
        "the feasible starts, hollow the others, the red line the feasible set's edge, ★ the "
        "improved start.",
    ),
    (
        "fig*b_best_*",
        "Actuator strokes x (m; rad for a rotary actuator) and velocities ẋ along the best "
        "motion (the paper's Figs. 4b and 5b), angles on an axis of their own on the right "
        "where lengths and angles mix; dashed: each actuator's stroke limits, in its colour "
        "(limits that coincide in turns of each colour).",
    ),
    (
        "fig4c_*",
        "The paper's Fig. 4c: the same on Fig. 4b's segment from a non-optimal start, the "
        "velocity sweep's least extended feasible start, on the velocity scale of Fig. 4b, so "
        "the two compare at a glance.",
    ),
    (
        "hydraulics_*",
        "The circuit along the best motion: pump flow Q_P and each cylinder's flow (L/min) "
        "with the pump's maximum dashed; each cylinder's load pressure p_L and the "
        "load-sensing pump pressure (bar), with the highest load pressure the supply serves "
        "dashed, and overrunning stretches (the load drives the cylinder) shaded across the "
        "panel in its colour; the pump power (kW) under load sensing (LS) and constant "
        "pressure (CP).",
    ),
    (
        "workspace*",
        "The task in its plane (m): each segment's path in its colour, and at each segment's "
        "improved start for the first objective the machine's cylinders from base to rod pin "
        "(thick, pale, in the segment's colour, each named once), its links as rods between "
        "the joints' origins (thin, in a dark shade of that colour), and the tool (●) where the "
        "segment begins; grey: the reachable area, tool "
        "points of 20,000 random configurations that keep every checked stroke.",
    ),
    (
        "cycle_strokes*",
        "Each actuator over one work cycle, one colour each: each strategy's first cycle "
        "(solid: free, dashed: drift-free), the per-segment plan's best motions dotted (they "
        "jump at the corners by the self-motions the plan leaves out); thick: each held "
        "actuator; thin dashed: stroke limits; grey lines: the corners between the segments "
        "named above; angles (a slew) on an axis of their own on the right. Below, the "
        "velocities.",
    ),
    (
        "cycle_drift*",
        "Above, how far each actuator ends a cycle from where it began (|drift| per cycle, log "
        f"scale; below {ROUNDING:g}, rounding, drawn at it), per strategy, the closing threshold "
        "dotted; below, how far each held actuator at each cycle's start has moved from its "
        "first value, and a stroke end it passes, dashed.",
    ),
    (
        "cycle_return_map*",
        "The return map P: the held actuator at a cycle's start against its value one cycle "
        "later (above, with the diagonal dashed) and the drift P(v) − v (below). Filled: starts "
        "whose cycle keeps the strokes, hollow: the others; ★ a limit cycle (a fixed point, "
        "filled where stable, |P'| < 1).",
    ),
    (
        "map_*",
        "Per objective, over the map's first two axes: the improved start's gain over the "
        "default start (%), only where both keep the strokes; the best initial value of each "
        "held actuator, one panel each; and the share of problems with a feasible start. "
        "Blank: no value.",
    ),
)


# With several held actuators the paper's peak curves are maps (`plots.peak_map_figure`): these
# caption them, before `CAPTIONS`.
MAP_CAPTIONS = (
    (
        "fig4a_*",
        "The paper's Fig. 4a over several held actuators: one panel per segment, over the "
        "initial values of the first two held actuators (any others as sampled, as the title "
        "says). Filled: the starts whose motion under the unweighted pseudoinverse keeps every "
        "checked stroke, coloured by its peak of ẋᵀẋ (m²/s²); hollow: the other reachable "
        "starts; red line: the feasible set's edge; ★ the improved start.",
    ),
    (
        "fig5a_*",
        "The paper's Fig. 5a over several held actuators: as Fig. 4a for the M_H-weighted "
        "pseudoinverse, coloured by the peak of ẋᵀ M_H ẋ, twice the kinetic energy (J). A "
        "segment with no feasible start has no filled start and no ★.",
    ),
)


def write_index(folder: Path | str, report: Path | str | None = None) -> Path:
    """Write ``folder/index.html`` (atomically) from the report in ``folder`` (or ``report``,
    where it was written elsewhere) and the figures and playbacks already in ``folder``;
    return its path. A map's folder holds ``summary.json`` instead of a report."""
    folder = Path(folder)
    source = Path(report) if report is not None else folder / "report.json"
    if not source.exists():
        source = folder / "summary.json"
    data = json.loads(source.read_text(encoding="utf-8"))
    files = sorted(p.name for p in folder.iterdir())
    if "summary" in data:
        title, body = _map_page(data, data["name"])
        # the heatmaps in the family's order of objectives, the rest by name
        order = [f"map_{o}.png" for o in data.get("objectives", [])]
        files.sort(key=lambda f: (order.index(f) if f in order else len(order), f))
    elif "studies" in data:
        title, body = _study_page(data)
    else:
        title, body = f"{data['robot']}: work cycle “{data['task']}”", _cycle_body(data)
    several = isinstance(_held(data), list)
    body += _figures(files, several) + _playbacks(files) + _data_files(files)
    page = Template((Path(__file__).parent / "report.html").read_text(encoding="utf-8"))
    text = page.substitute(title=_e(title), body=body)
    path = folder / "index.html"
    write_atomically(path, lambda p: p.write_text(text, encoding="utf-8"))
    return path


def _e(value) -> str:
    return html.escape(str(value))


def _number(value, digits: int = 4) -> str:
    """A number to ``digits`` significant digits (several, one per held actuator, joined); a
    missing one as a dash."""
    if isinstance(value, list):
        return ", ".join(_number(v, digits) for v in value)
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | float):
        return f"{value:.{digits}g}"
    return str(value)


def _rounded(value) -> str:
    """A change (a corner's Δ, a drift) to 3 significant digits, one below the integration's
    rounding (`ROUNDING`) as 0."""
    if isinstance(value, int | float) and abs(value) < ROUNDING:
        value = 0.0
    return _number(value, 3)


def _percent(value) -> str:
    """A percentage to 0.01, a solver's −3e-10 shown as 0.00; a missing one as a dash."""
    return "–" if value is None else f"{value:z.2f}"


def _range(pair) -> str:
    """A feasible range [low, high], or one per held actuator, [[low, high], ...]."""
    if pair is None:
        return "none"
    if isinstance(pair[0], list):
        return "; ".join(_range(p) for p in pair)
    return f"{pair[0]:.4g} – {pair[1]:.4g}"


def _table(rows: list[dict], caption: str = "") -> str:
    """A table whose column names carry their units; cells are formatted already."""
    import pandas as pd  # where used: the command loads it only when it writes a page

    if not rows:
        return ""
    frame = pd.DataFrame(rows).fillna("–")
    text = frame.to_html(index=False, escape=True, border=0)
    return (f"<p>{_e(caption)}</p>\n" if caption else "") + f'<div class="wide">{text}</div>\n'


def _units(report: dict, names: str | list[str] | None = None) -> str:
    """The SI unit of the actuators ``names`` (all where None), from the report's units."""
    units = report["units"]
    chosen = units if names is None else [names] if isinstance(names, str) else names
    return " or ".join(sorted({units[name] for name in chosen}))


def _limits(violations: list[str]) -> str:
    return "kept" if not violations else "; ".join(violations)


def _headline(study: dict, s: dict, held: str, units: dict[str, str]) -> str:
    """One segment's best start and peak under one objective, as a list item: the held values,
    and the other actuators' strokes there, which tell the configuration where the held values
    alone do not (an arm whose two elbows reach the start; a report written before the strokes
    were, without them)."""
    if s["best"] is None:
        return (
            f"<li>{study['objective']}, segment {_e(s['name'])}: no start keeps the "
            f"limits; closest: {_e(s['closest_violation'])}</li>"
        )
    gap = s["gap_percent"]
    above = "" if gap is None else f", {_percent(gap)} % above the bound"
    held_names = (
        s["held_actuator"] if isinstance(s["held_actuator"], list) else [s["held_actuator"]]
    )
    others = ", ".join(
        f"{name} = {_number(value)} {units[name]}"
        for name, value in s["best"].get("strokes", {}).items()
        if name not in held_names
    )
    beside = f" ({_e(others)})" if others else ""
    kinds = {units.get(name, "") for name in held_names}
    unit = f" {kinds.pop()}" if len(kinds) == 1 else ""  # one unit for every held value
    return (
        f"<li>{study['objective']}, segment {_e(s['name'])}: improved start {held} = "
        f"{_number(s['best']['value'])}{unit}{beside}, {study['measure']} "
        f"{s['best']['peak']:.4g} {study['unit']}{above}</li>"
    )


def _search(report: dict, several_held: bool) -> str:
    """How the study searched the improved starts, in the words of docs/machines.md: the fast
    search, the paper's uniform sweep, or, with ``several_held`` actuators, Halton points
    refined by compass search; with the samples of the sweep behind the figures."""
    samples = report["samples"]
    if report["method"] == "fast":
        return f"{samples} samples, the fast search"
    if several_held:
        return (
            f"{samples} Halton points over the held strokes, the best feasible refined by "
            "compass search"
        )
    return f"{samples} samples, the uniform sweep"


def _study_page(report: dict) -> tuple[str, str]:
    title = f"{report['robot']}: {report['task']}"
    studies = report["studies"]
    segments = [s["name"] for s in studies[0]["segments"]] if studies else []
    names = _held(report)
    held, held_unit = (_number(names), _units(report, names)) if names else ("–", "")
    lines = [
        _headline(study, s, held, report["units"]) for study in studies for s in study["segments"]
    ]
    summary = (
        f'<div class="summary"><p>The improved start of the held <b>{_e(held)}</b> on '
        f"segments {_e(', '.join(segments))} of the task {_e(report['task'])!r}, objectives "
        f"{_e(' and '.join(s['objective'] for s in studies))}: payload "
        f"{report['payload']:g} kg, {_e(_search(report, isinstance(names, list)))}, strokes "
        f"checked: {_e(', '.join(report['checked_actuators']))}. Held values "
        f"are in {held_unit}.</p><ul>{''.join(lines)}</ul></div>\n"
    )
    body = summary + "<h2>Improved start and bound, per segment</h2>\n"
    for study in studies:
        measure = f"{study['measure']} ({study['unit']})"
        rows = [
            {
                "segment": s["name"],
                "held": _number(s["held_actuator"]),
                f"feasible starts ({held_unit})": _range(s["feasible_range"]),
                f"best start ({held_unit})": _number(s["best"] and s["best"]["value"]),
                measure: _number(s["best"] and s["best"]["peak"]),
                f"bound, {measure}": _number(s["bound"] and s["bound"]["peak"]),
                "gap to bound (%)": _percent(s["gap_percent"]),
                "motions": s["simulations"],
                "note": s["closest_violation"] or s.get("bound_failure") or "",
            }
            for s in study["segments"]
        ]
        body += f"<h3>{_e(study['objective'])} objective: min {_e(study['measure'])}</h3>\n"
        body += _table(rows)
    actuators = [SimpleNamespace(name=n, rotary=u == "rad") for n, u in report["units"].items()]
    squared = VELOCITY.unit_of(actuators)
    # what the column checks: the strokes, and the circuit's limits where they count
    limits = "strokes, circuit" if report.get("circuit_limits_checked") else "strokes"
    rows = [
        {
            "segment": r["segment"],
            "strategy": r["strategy"],
            f"start ({held_unit})": _number(r["start_value"]),
            f"peak ẋᵀẋ ({squared})": _number(r["peak_velocity_norm"]),
            "peak ẋᵀ M_H ẋ (J)": _number(r["peak_kinetic"]),
            "largest tracking error (m)": _number(r.get("max_tracking_error"), 2),
            limits: _limits(r["violations"]),
        }
        for r in report["comparison"]
    ]
    body += "<h2>Strategies compared</h2>\n" + _table(
        rows, "Every strategy on every segment; start: the held actuator's."
    )
    body += _hydraulics(report["comparison"], report.get("energy_bounds"))
    cycle = report.get("cycle") or {}
    if "skipped" in cycle:
        body += f"<h2>Work cycle</h2>\n<p>No cycle section: {_e(cycle['skipped'])}</p>\n"
    elif cycle:
        body += "<h2>Work cycle</h2>\n" + _cycle_body(cycle)
    return title, body


def _hydraulics(comparison: list[dict], bounds: dict | None) -> str:
    rows = []
    for r in comparison:
        h = r.get("hydraulics")
        if h is None:
            continue
        above = h.get("above_energy_bound_percent", {})
        beyond = "beyond the circuit's physics" if h.get("unphysical") else None
        unserved = {s: f"past what {s} serves" for s in h.get("unserved", [])}
        rows.append(
            {
                "segment": r["segment"],
                "strategy": r["strategy"],
                "peak pump flow Q_P (L/min)": _number(h["peak_pump_flow_l_min"], 3),
                "highest load pressure (bar)": beyond or _number(h["max_load_pressure_bar"], 3),
                "LS energy (kJ)": beyond or unserved.get("LS") or _number(h["ls_energy_kj"]),
                "CP energy (kJ)": beyond or unserved.get("CP") or _number(h["cp_energy_kj"]),
                **(
                    {
                        f"above {s} bound (%)": beyond or unserved.get(s) or _percent(above.get(s))
                        for s in ("LS", "CP")
                    }
                    if bounds
                    else {}  # no energy bound asked for: no column of dashes
                ),
                "shortest duration (s)": h.get("shortest_duration_reason")
                or _number(h["shortest_duration_s"], 3),
                "overrunning": _number(h["overrunning"]),
                "circuit": _limits(h["violations"]),
            }
        )
    if not rows:
        return ""
    text = "<h2>Hydraulics</h2>\n" + _table(
        rows,
        "Per motion, in the quasi-static meter-in model: LS, a load-sensing pump; CP, a "
        "constant-pressure one; the shortest duration of the same path within the cylinders' "
        "speeds and accelerations and the pump's flow.",
    )
    bound_rows = [
        {
            "segment": segment,
            "supply": supply,
            "energy bound (kJ)": _number(b["energy_kj"]),
            "last refinement's change (%)": _percent(
                None if b["change"] is None else 100 * b["change"]
            ),
            "converged": _number(b["converged"]),
            "note": b.get("failure") or "",
        }
        for segment, supplies in (bounds or {}).items()
        for supply, b in supplies.items()
    ]
    return text + _table(bound_rows, "The least pump energy over every held actuator history.")


def _priced(cycle: dict) -> dict[str, str]:
    """The words the strategies' table heads the cycle's figures with, units aside, by their
    keys in the report (a strategy's, and ``periodic_versus_free_percent``'s)."""
    return {
        "objective": cycle["measure"],
        "ls_energy_kj": "LS energy per cycle",
        "cp_energy_kj": "CP energy per cycle",
    }


def _cycle_body(cycle: dict) -> str:
    """The work cycle: plans, corners, strategies with their drift, the return map."""
    held, held_unit = _number(cycle["held_actuator"]), _units(cycle, cycle["held_actuator"])
    priced = _priced(cycle)
    measure = f"{priced['objective']} ({cycle['unit']})"
    whole = cycle["whole_cycle"]
    per = cycle["per_segment"]
    path = " → ".join(s["name"] for s in cycle["segments"])
    best = whole["best"]
    text = (
        f'<div class="summary"><p>The cycle {_e(path)} ({cycle["duration_s"]:.2f} s) run '
        f"continuously, {cycle['cycles']} cycles, {_e(cycle['objective'])} objective, held "
        f"actuator {_e(held)} (values in {held_unit}). Whole-cycle improved start: "
        + (
            f"{held} = {_number(best['value'])} (feasible {_range(whole['feasible_range'])}), "
            f"{measure} {best['peak']:.4g}."
            if best
            else f"none keeps the limits ({_e(whole.get('closest_violation'))})."
        )
        + "</p></div>\n"
    )
    segments = [
        {
            "segment": s["name"],
            "path": s["path"],
            "length (m)": _number(s["length_m"]),
            "duration (s)": _number(s["duration_s"]),
            "speed (m/s)": _number(s["speed"]),
        }
        for s in cycle["segments"]
    ]
    text += _table(segments, "The cycle's segments.")
    plan = [
        {
            "segment": s["name"],
            f"best start ({held_unit})": _number(s["best"] and s["best"]["value"]),
        }
        | {measure: _number(s["best"] and s["best"]["peak"])}
        for s in per["segments"]
    ]
    text += _table(
        plan, "The per-segment plan (the paper's method): each segment from its own best start."
    )
    corners = [
        {"corner": f"{c['after']} → {c['before']}"}
        | {  # no Δ where a segment beside the corner has no feasible start
            f"Δ{name} ({_units(cycle, name)})": _rounded(d)
            for name, d in (c["delta"] or dict.fromkeys(cycle["units"])).items()
        }
        | {
            "time (s)": _number(c["time_s"], 3),
            f"held speed ({held_unit}/s)": _number(c["speed"]),
            "self-motion": "keeps the strokes"
            if c["self_motion_within_limits"]
            else (c["reason"] or "passes a limit"),
        }
        for c in per["corners"]
    ]
    text += _table(
        corners,
        "The self-motion the per-segment plan needs at each corner (the tool held still)"
        + (
            ""  # a corner beside a segment with no feasible start has none
            if per["self_motion_time_s"] is None
            else f": {per['self_motion_time_s']:.2f} s per cycle in all."
        ),
    )
    strategies = []
    for s in cycle["strategies"].values():
        repetition = s.get("repetition") or {}
        drift = repetition.get("largest_drift_per_cycle") or [None]
        tool = repetition.get("tool_drift_per_cycle") or [None]
        strategies.append(
            {
                "strategy": s["name"],
                measure: _number(s["objective"]),
                f"{priced['ls_energy_kj']} (kJ)": _number(s.get("ls_energy_kj")),
                f"{priced['cp_energy_kj']} (kJ)": _number(s.get("cp_energy_kj")),
                f"largest drift, first cycle ({_units(cycle)})": _rounded(drift[0]),
                f"largest drift, last cycle ({_units(cycle)})": _rounded(drift[-1]),
                "tool drift, last cycle (m)": _rounded(tool[-1]),
                "first cycle past a stroke": _number(repetition.get("first_cycle_past_a_limit")),
                "settling": repetition.get("settling", "–"),
            }
        )
    text += _table(
        strategies, "Each strategy repeated; drift: where a cycle ends minus where it began."
    )
    passed = [
        {"strategy": s["name"], "circuit, first cycle": _limits(s["circuit_violations"])}
        for s in cycle["strategies"].values()
        if s.get("circuit_violations")
    ]
    text += _table(
        passed,
        "The limits of the circuit (load pressures, pump flow, cylinder speeds) and of the "
        "cylinders' accelerations each strategy passes in its first cycle, t in the cycle's "
        "time.",
    )
    versus = cycle.get("periodic_versus_free_percent")
    if versus:
        change = ", ".join(f"{priced[k]} {v:+.1f} %" for k, v in versus.items())
        failure = (cycle.get("periodic") or {}).get("failure")
        caveat = f" The periodic plan is not shown optimal: {failure}." if failure else ""
        text += (
            f"<p>The drift-free strategy against the free improved cycle: {_e(change)}."
            f"{_e(caveat)}</p>\n"
        )
    mapped = cycle.get("return_map") or {}
    points = [
        {
            f"limit cycle {held} ({held_unit})": _number(p["value"], 5),
            "slope P'": _number(p["slope"], 3),
            "stable": _number(p["stable"]),
            "keeps the strokes": _number(p.get("keeps_the_strokes")),
        }
        for p in mapped.get("fixed_points", [])
    ]
    text += _table(points, "The return map's fixed points: the limit cycles of the free law.")
    for part, why in cycle.get("failures", {}).items():  # what the cycle study left out
        text += f'<p class="note">Not computed, {_e(part.replace("_", " "))}: {_e(why)}</p>\n'
    return text


def _map_page(summary: dict, name: str) -> tuple[str, str]:
    text = (
        f'<div class="summary"><p>{_e(summary["summary"])}</p><p>{summary["problems"]} '
        f"problems, {summary['rows']} rows (one per problem and objective) in "
        '<a href="map.parquet">map.parquet</a>; read it with <code>pandas.read_parquet</code>.'
        "</p></div>\n"
    )
    return f"design map {name}", text


def _held(report: dict) -> str | list[str] | None:
    """The held actuator's name, or the held actuators' names, from a study's or a cycle's
    report; None in a map's summary or a study of no segment."""
    if "held_actuator" in report:
        return report["held_actuator"]
    studies = report.get("studies") or [{}]
    segments = studies[0].get("segments") or [{}]
    return segments[0].get("held_actuator")


def _caption(name: str, several_held: bool = False) -> str:
    """The caption of figure file ``name``: the first of `CAPTIONS` whose pattern it matches,
    with several held actuators the first of `MAP_CAPTIONS` before them."""
    captions = (*MAP_CAPTIONS, *CAPTIONS) if several_held else CAPTIONS
    return next((text for pattern, text in captions if fnmatch(name, pattern)), "")


FIGURE_ORDER = (  # a figure's place on the page by how its name starts (docs/report.md)
    "fig",  # the paper's 4 and 5, then any other objective's, by name
    "hydraulics_best_velocity",
    "hydraulics_",
    "workspace",
    "cycle_strokes",
    "cycle_drift",
    "cycle_return_map",
    "",  # any other, last
)


def _figures(files: Iterable[str], several_held: bool = False) -> str:
    """Every figure among ``files``, captioned (`_caption`), in `FIGURE_ORDER`, then in the
    order given (by name, or a map's objectives')."""

    def place(name: str) -> int:  # a stable sort: files of one place keep their order
        return next(i for i, start in enumerate(FIGURE_ORDER) if name.startswith(start))

    shown = [
        f'<figure><img src="{_e(f)}" alt="{_e(f)}"><figcaption><b>{_e(f)}</b>. '
        f"{_e(_caption(f, several_held))}</figcaption></figure>\n"
        for f in sorted(files, key=place)
        if f.endswith(".png")
    ]
    return "<h2>Figures</h2>\n" + "".join(shown) if shown else ""


def _playbacks(files: Iterable[str]) -> str:
    """Links to the playback pages: what each plays, from its file name."""
    items = []
    for f in files:
        if not (f.startswith("playback_") and f.endswith(".html")):
            continue
        shown = f[len("playback_") : -len(".html")]
        what = next((o for o in ("cycle", *OBJECTIVES) if shown.startswith(f"{o}_")), None)
        rest = shown[len(what) + 1 :] if what else shown
        words = (
            f"the {rest} strategy's first whole cycle"
            if what == "cycle"
            else f"segment {rest} from the best start, {what} objective"
        )
        items.append(f'<li><a href="{_e(f)}">{_e(f)}</a>: {_e(words)}</li>')
    if not items:
        return ""
    return (
        "<h2>Playbacks</h2>\n<p>Each page plays a motion in 3-D, offline; add <code>?t=2.5</code>"
        " to its address to see that instant, paused.</p>\n<ul>" + "".join(items) + "</ul>\n"
    )


def _data_files(files: Iterable[str]) -> str:
    data = [f for f in files if f.endswith((".json", ".csv", ".parquet"))]
    links = ", ".join(f'<a href="{_e(f)}">{_e(f)}</a>' for f in data)
    return f"<h2>Data</h2>\n<p>{links}</p>\n" if data else ""
