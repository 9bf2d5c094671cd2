"""The study's figures (matplotlib): the paper's Figs. 4a-4c, 5a and 5b, with a hydraulic
circuit pump flow and pressures along the best motions, and the work cycle's: strokes over the
cycle, drift against cycle number, the return map.

Figures read results; they compute nothing of their own.
"""

from __future__ import annotations

import re
from functools import partial
from pathlib import Path

import numpy as np

from redundancy.model.actuators import LinearCylinder
from redundancy.model.hydraulics import BAR, LITRES_PER_MINUTE
from redundancy.model.linkage import LinkageCylinder
from redundancy.model.robot import AXES
from redundancy.planning.cycles import ReturnMap
from redundancy.planning.ik import named_values
from redundancy.planning.integrate import Trajectory
from redundancy.planning.starts import SearchResult
from redundancy.resolution.objectives import VELOCITY
from redundancy.study.cycles import CycleStudy
from redundancy.study.output import write_atomically
from redundancy.study.study import Study

DPI = 110  # dots per inch of the written figures
PNG_COMPRESSION = 1  # zlib level of the written figures: the fastest
TITLE_SPAN = 0.9  # of a figure's width, the most its title takes: clear of the edges by more
# than the layout's padding, so that laying the figure out again does not move it


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend, imported when first drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def unit(actuators, rate: str = "") -> str:
    """The unit of all the ``actuators`` as a label: "m", "rad", or, for a mix, "m; rad for"
    the rotary ones; ``rate`` appends a time derivative ("/s")."""
    rotary = [a.name for a in actuators if a.rotary]
    if not rotary:
        return f"m{rate}"
    if len(rotary) == len(actuators):
        return f"rad{rate}"
    return f"m{rate}; rad{rate} for {', '.join(rotary)}"


def peaks_figure(
    searches: tuple[SearchResult, ...], title: str, chosen: tuple[SearchResult, ...] | None = None
):
    """Peak of the objective against the held actuator's start value, one curve per segment
    (each search's samples), feasible samples solid, the best start a star and the feasible
    range shaded: ``chosen``'s, the search that chose it and located the range's ends (the
    study's tables give both), by default the curve's own (Figs. 4a, 5a).
    With several held actuators, each sample is a point over the first of them (two held
    actuators have `peak_map_figure`)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    plt = pyplot()
    figure, axes = plt.subplots(figsize=(7, 4.5))
    style = "o-" if len(searches[0].held) == 1 else "o"
    for search, choice in zip(searches, chosen or searches):
        reachable = sorted(
            (s for s in search.samples if s.peak is not None), key=lambda s: s.values
        )
        none = "" if search.feasible else ": no feasible start"
        line = axes.plot(
            [s.values[0] for s in reachable],
            [s.peak for s in reachable],
            ":" if len(search.held) == 1 else ".",
            alpha=0.6,
            label=f"segment {search.segment.name}{none}",
        )[0]
        feasible = sorted(search.feasible, key=lambda s: s.values)
        colour = line.get_color()
        axes.plot(
            [s.values[0] for s in feasible], [s.peak for s in feasible], style, ms=2.5, color=colour
        )
        if choice.feasible_box is not None:  # as the search that chose the star located it
            axes.axvspan(*choice.feasible_box[0], color=colour, alpha=0.08)
        if choice.best is not None:
            axes.plot(choice.best.values[0], choice.best.peak, "*", ms=12, color=colour)
    objective, held = searches[0].objective, searches[0].held[0]
    measure = objective.value_axis(searches[0].robot.actuators)
    along = f"initial {held} ({searches[0].robot.actuators[held].unit})"
    segments = {"loc": "upper left", "fontsize": 8}
    _labelled(figure, title, (measure,), along, segments)
    axes.add_artist(axes.get_legend())  # kept beside the encodings' own legend
    grey = "0.35"
    encodings = [
        Line2D([], [], ls=":", color=grey, label="every reachable start"),
        Line2D([], [], ls="-", marker="o", ms=2.5, color=grey, label="keeps every stroke"),
        Patch(color=grey, alpha=0.15, label="feasible range"),
        Line2D([], [], ls="", marker="*", ms=10, color=grey, label="improved start"),
    ]
    axes.legend(handles=encodings, loc="upper right", fontsize=8)
    return figure


def peak_map_figure(
    searches: tuple[SearchResult, ...], title: str, chosen: tuple[SearchResult, ...] | None = None
):
    """With two or more held actuators: per segment, the peak of the objective over the box of
    the first two's start values, at every reachable sample (colour), the feasible set outlined
    (the level ½ of the samples' feasibility, interpolated over their triangulation), feasible
    samples filled and the others hollow, the best start a star (``chosen``'s, by default the
    search's own)."""
    plt = pyplot()
    count = len(searches)
    figure, panes = plt.subplots(1, count, figsize=(4.6 * count, 4.4), squeeze=False)
    objective, held = searches[0].objective, searches[0].held
    for pane, search, choice in zip(panes[0], searches, chosen or searches):
        reachable = [s for s in search.samples if s.peak is not None]
        x, y = (np.array([s.values[i] for s in reachable]) for i in (0, 1))
        peak = np.array([s.peak for s in reachable])
        feasible = np.array([s.feasible for s in reachable])
        shown = pane.scatter(x[feasible], y[feasible], c=peak[feasible], s=14, cmap="viridis")
        pane.scatter(x[~feasible], y[~feasible], s=14, facecolors="none", edgecolors="0.55", lw=0.6)
        if feasible.any() and (~feasible).any() and len(reachable) >= 3:
            pane.tricontour(x, y, feasible.astype(float), levels=[0.5], colors="crimson")
        if choice.best is not None:
            pane.plot(*choice.best.values[:2], "*", ms=14, color="crimson")
        actuators = search.robot.actuators
        box = [actuators[h] for h in held]
        pane.set_xlim(box[0].lower, box[0].upper)
        pane.set_ylim(box[1].lower, box[1].upper)
        pane.set_xlabel(f"initial {held[0]} ({actuators[held[0]].unit})")
        pane.set_ylabel(f"initial {held[1]} ({actuators[held[1]].unit})")
        pane.set_title(f"segment {search.segment.name}")
        if feasible.any():
            figure.colorbar(shown, ax=pane, label=objective.value_axis(actuators))
    rest = held[2:]  # drawn over the first two; the others vary among the samples
    over = f"\nover {held[0]} and {held[1]}; {', '.join(rest)} as sampled" if rest else ""
    figure.tight_layout()
    suptitled(figure, f"{title}; red: the feasible set's edge, ★ best, hollow: not feasible{over}")
    figure.tight_layout()
    return figure


def limit_dashes(row: int, count: int) -> tuple[int, tuple[int, int]]:
    """The dash pattern of actuator ``row``'s stroke limits among ``count``: dashes of 3 points
    with room for the others' between them, shifted by its row, so that limits that coincide
    (the crane's x1 and x2 share their stroke) show every colour in turn."""
    return (3 * row, (3, 3 * max(count - 1, 1)))


def _by_unit(axes, actuators) -> list:
    """The axes each actuator is drawn on: ``axes``, and where lengths and angles mix, a twin
    on the right for the angles, so that a slew's radians do not squash the cylinders' metres."""
    rotary = [a.rotary for a in actuators]
    if all(rotary) or not any(rotary):
        return [axes] * len(rotary)
    twin = axes.twinx()
    return [twin if turning else axes for turning in rotary]


def _still(axes) -> None:
    """Scale ``axes`` ±0.1 about its lines' value where they vary by rounding alone (a slew that
    stays put: its velocity of 1e-63 rad/s is no scale to read)."""
    values = np.concatenate([line.get_ydata() for line in axes.get_lines()] or [np.zeros(1)])
    values = values[np.isfinite(values)]
    if values.size and np.ptp(values) < 1e-9:
        middle = round(float(values.mean()), 9)
        axes.set_ylim(middle - 0.1, middle + 0.1)


def _twin_label(axes, drawn: list, label: str) -> None:
    """Label the angles' axes among ``drawn`` (a twin of ``axes``, `_by_unit`) ``label``."""
    for twin in dict.fromkeys(drawn):
        if twin is not axes:
            twin.set_ylabel(label)


def _key(axes, drawn: list, label: str, **legend) -> None:
    """`_twin_label`, and one legend on ``axes`` of every line drawn on it and its twin."""
    _twin_label(axes, drawn, label)
    handles = [h for a in dict.fromkeys(drawn) for h in a.get_legend_handles_labels()[0]]
    axes.legend(handles=handles, **legend)


def motion_figure(trajectory: Trajectory, title: str):
    """Actuator displacements and velocities along one motion (Figs. 4b, 4c, 5b), with the
    stroke limits dashed; where lengths and angles mix, the angles on an axis of their own on
    the right."""
    plt = pyplot()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    actuators = trajectory.robot.actuators
    t = trajectory.t[0]
    tops, bottoms = _by_unit(top, actuators), _by_unit(bottom, actuators)
    for row, actuator in enumerate(actuators):
        colour = f"C{row}"
        tops[row].plot(t, trajectory.x[0, :, row], color=colour, label=actuator.name)
        for bound in (actuator.lower, actuator.upper):
            dashes = limit_dashes(row, len(actuators))
            tops[row].axhline(bound, ls=dashes, lw=0.8, color=colour, alpha=0.6)
        bottoms[row].plot(
            t, trajectory.x_dot[0, :, row], color=colour, label=f"ẋ of {actuator.name}"
        )
    lengths = [a for a in actuators if not a.rotary] or list(actuators)
    angles = [a for a in actuators if a.rotary] or list(actuators)
    what = ("actuator displacement x", "actuator velocity ẋ")
    _labelled(
        figure,
        title + "\ndashed: stroke limits",
        (f"{what[0]} ({unit(lengths)})", f"{what[1]} ({unit(lengths, rate='/s')})"),
        legend={},
    )
    right = (f"{what[0]} ({unit(angles)})", f"{what[1]} ({unit(angles, rate='/s')})")
    for axes, drawn, label in zip((top, bottom), (tops, bottoms), right):
        _key(axes, drawn, label, loc="best", fontsize=8)
        for shown in dict.fromkeys(drawn):
            _still(shown)
    figure.tight_layout()  # room for the angles' labels on the right
    return figure


def hydraulics_figure(trajectory: Trajectory, title: str):
    """The circuit along one motion, read from its `flows`: flows Q_P, Q (L/min), pressures
    p_L and the pump's (bar), pump power p_P Q_P (kW); its caption (`report.CAPTIONS`) says
    the encodings."""
    plt = pyplot()
    circuit, flows = trajectory.robot.circuit(), trajectory.flows
    figure, (top, middle, bottom) = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    t = trajectory.t[0]
    top.plot(t, flows.pump_flow[0] / LITRES_PER_MINUTE, "k", lw=1.5, label="pump flow Q_P")
    top.axhline(
        circuit.pump_flow / LITRES_PER_MINUTE, ls="--", lw=0.8, color="k", label="pump maximum"
    )
    for column, name in enumerate(circuit.names):
        colour = f"C{column}"
        top.plot(
            t, flows.flow[0, :, column] / LITRES_PER_MINUTE, color=colour, label=f"Q of {name}"
        )
        load = flows.load[0, :, column] / BAR
        middle.plot(t, load, color=colour, label=f"p_L of {name}")
        overrun = flows.overrunning[0, :, column]
        if overrun.any():
            shaded = {"color": colour, "alpha": 0.15, "lw": 0, "label": f"{name} overrunning"}
            across = middle.get_xaxis_transform()  # the panel's height: a p_L near 0 shows too
            middle.fill_between(t, 0, 1, where=overrun, transform=across, **shaded)
    middle.plot(
        t, flows.pump_pressure(circuit.load_sensing)[0] / BAR, "k", lw=1, label="LS pump pressure"
    )
    available = circuit.supply.available(circuit.relief) / BAR
    middle.axhline(available, ls="--", lw=0.8, color="k", label="highest load served")
    for supply, name, style in (
        (circuit.load_sensing, "LS", "-"),
        (circuit.constant_pressure, "CP", "--"),
    ):
        bottom.plot(t, flows.power(supply)[0] / 1000, "k" + style, lw=1, label=f"{name} pump power")
    beside = {"loc": "center left", "bbox_to_anchor": (1.01, 0.5), "fontsize": 8}
    labels = ("flow (L/min)", "pressure (bar)", "pump power (kW)")
    return _labelled(figure, title, labels, legend=beside)


def _labelled(
    figure,
    title: str,
    labels: tuple[str, ...],
    along: str = "t (s)",
    legend: dict | None = None,
    pad: float | None = None,
):
    """Label a figure of one or more plots over one horizontal axis (by default time t, s), from the
    top down by ``labels``: title (``pad`` points above the top plot, by default matplotlib's),
    grids and a legend in each, placed by ``legend`` (matplotlib's `legend` options; default:
    where it hides least, small; {}: no legend)."""
    for axes, label in zip(figure.axes, labels):
        axes.set_ylabel(label)
        axes.grid(alpha=0.3)
        if legend != {}:
            axes.legend(**(legend or {"loc": "best", "fontsize": 8}))
    figure.axes[len(labels) - 1].set_xlabel(along)  # the lowest labelled, not a twin
    titled(figure.axes[0], title, pad=pad)
    return figure


def titled(axes, title: str, **options) -> None:
    """Lay out ``axes``' figure, then title ``axes`` (matplotlib's `set_title` ``options``)
    with ``title`` broken into lines (`wrapped`) that, centred over the axes, stay within
    `TITLE_SPAN` of the figure, and lay it out again: a title wider than its figure is cut at
    the edges, which no layout can undo."""
    figure = axes.figure
    figure.tight_layout()
    text = axes.set_title(title, **options)
    centre = axes.bbox.x0 + axes.bbox.width / 2
    room = 2 * min(centre, figure.bbox.width - centre) * TITLE_SPAN
    text.set_text(wrapped(title, figure, room, text.get_fontproperties()))
    figure.tight_layout()


def suptitled(figure, title: str) -> None:
    """Title ``figure`` with ``title`` broken into lines (`wrapped`) within `TITLE_SPAN` of its
    width, so that nothing is cut at its edges."""
    text = figure.suptitle(title)
    room = figure.bbox.width * TITLE_SPAN
    text.set_text(wrapped(title, figure, room, text.get_fontproperties()))


def wrapped(text: str, figure, room: float, font) -> str:
    """``text`` with each of its lines broken so that none is wider than ``room`` (display units
    of ``figure``) in ``font``: after a comma where that is enough ("x2 = 1375 mm" stays whole),
    else between words; a word wider than that stays whole."""
    renderer = figure.canvas.get_renderer()

    def fits(line: str) -> bool:
        return renderer.get_text_width_height_descent(line, font, ismath=False)[0] <= room

    def filled(pieces: list[str]) -> list[str]:
        """The pieces joined by spaces, as many to a line as fit."""
        lines = [pieces[0]]
        for piece in pieces[1:]:
            joined = f"{lines[-1]} {piece}"
            lines[-1:] = [joined] if fits(joined) else [lines[-1], piece]
        return lines

    return "\n".join(
        line if fits(line) else "\n".join(filled(line.split(" ")))
        for paragraph in text.split("\n")
        for line in filled(re.split(r"(?<=,) ", paragraph))
    )


def write_figures(study: Study, folder: Path, segment: str | None = None) -> list[Path]:
    """Write `study_figures` into ``folder``; return their paths."""
    return write_pngs(study_figures(study, segment), folder)


def study_figures(study: Study, segment: str | None = None) -> dict:
    """The paper's figures for the study by file name.

    ``segment`` is the one shown in the motion figures (default: per objective, the first with
    an improved start, `Study.shown_segment`). With a cycle section, the cycle's figures too
    (`cycle_figures`).
    """
    figures = {}
    numbers = {"velocity": "4", "energy": "5"}  # the paper's figures; the others unnumbered
    for name, searches in study.searches.items():
        number = numbers.get(name, "")
        value = searches[0].objective.value_label
        drawn = peaks_figure if len(study.held) == 1 else peak_map_figure
        figures[f"fig{number}a_peak_{name}.png"] = drawn(
            study.sweeps[name],
            f"{value[0].upper()}{value[1:]} against the initial {' and '.join(study.held)}",
            searches,
        )
        shown = segment or study.shown_segment(name)
        if shown is not None:
            figures |= motion_figures(study, name, shown, number)
    if len(study.robot.task_axes) >= 2:  # a task along one axis has no plane to draw
        objective = study.searches[next(iter(study.searches))][0].objective
        figures["workspace.png"] = workspace_figure(
            study,
            "The task, the reachable area and the machine at each best start, "
            f"min {objective.label}",
        )
    if study.cycle_study is not None:
        figures.update(cycle_figures(study.cycle_study))
    return figures


def motion_figures(study: Study, objective: str, segment: str, number: str) -> dict:
    """The motions of ``objective`` on ``segment`` by file name, where it has an improved
    start: the best one (the paper's Figs. 4b, 5b; numbered ``number``) and the circuit along
    it; for the velocity objective, Fig. 4c too, the motion from the sweep's least extended
    feasible start (`Study.nonoptimal`), on Fig. 4b's velocity scale."""
    search = study.search(objective, segment)
    if search.best is None:
        return {}
    value = search.objective.value_label
    best = search.best_motion  # as the study ran it
    start = named_values(study.robot, study.held, search.best.values)
    optimal = motion_figure(best, f"min {value}, segment {segment}, optimal start {start}")
    figures = {f"fig{number}b_best_{objective}_{segment}.png": optimal}
    if study.robot.hydraulics is not None:
        figures[f"hydraulics_best_{objective}_{segment}.png"] = hydraulics_figure(
            best, f"Pump flow and pressures: min {value}, segment {segment}"
        )
    found = study.nonoptimal(segment) if objective == VELOCITY.name else None
    if found is not None:
        other, motion = found
        nonoptimal = motion_figure(
            motion,
            f"min {value}, segment {segment}, non-optimal feasible start "
            f"{named_values(study.robot, study.held, other.values)}",
        )
        nonoptimal.axes[1].sharey(optimal.axes[1])  # one range, the union of theirs: to compare
        nonoptimal.axes[1].autoscale_view(scalex=False)  # sharing alone keeps Fig. 4b's range
        figures[f"fig4c_nonoptimal_{objective}_{segment}.png"] = nonoptimal
    return figures


def workspace_figure(study: Study, title: str):
    """The task in its plane (the first two task axes, m), the machine at each segment's
    improved start for the first objective (its best motion's first state, `Study.best_poses`)
    and the reachable area the study sampled (`Study.reachable`), as its caption says."""
    from matplotlib.colors import to_rgb

    plt = pyplot()
    robot = study.robot
    rows = [AXES.index(a) for a in robot.task_axes][:2]
    figure, axes = plt.subplots(figsize=(9, 5.5))
    first = next(iter(study.searches))
    motions = study.best_motions
    if study.reachable is not None:
        axes.scatter(*study.reachable[:, :2].T, s=1, color="0.85", rasterized=True, zorder=0)
        axes.plot([], [], "s", color="0.85", label="reachable, strokes kept (sampled)")
    named: set[str] = set()  # each cylinder named once, at the first machine drawn
    for i, segment in enumerate(study.cycle.segments):
        colour = f"C{i}"
        path = segment.outline()[:, : len(rows)]
        axes.plot(*path.T, color=colour, lw=2, label=f"segment {segment.name}")
        axes.annotate(segment.name, path.mean(axis=0), color=colour, fontsize=9)
        motion = motions.get((first, segment.name))
        if motion is None or motion.space is None:
            continue
        dark = tuple(0.55 * c for c in to_rgb(colour))  # its links: apart from its path
        for a, b in study.best_poses[first, segment.name][:, :, rows]:
            axes.plot(*np.transpose([a, b]), lw=1.5, color=dark)
        kinematics = motion.space.kinematics
        for actuator in robot.actuators:
            if isinstance(actuator, LinearCylinder | LinkageCylinder):
                base, rod = (end[0, rows] for end in actuator.ends(kinematics))
                axes.plot(*np.transpose([base, rod]), lw=5, alpha=0.4, color=colour)
                if actuator.name not in named:
                    named.add(actuator.name)
                    axes.annotate(actuator.name, (base + rod) / 2, fontsize=8, color="0.3")
        axes.plot(*robot.tool(kinematics).position[0, rows], "o", color=colour)
    grey = "0.45"
    axes.plot([], [], lw=5, alpha=0.4, color=grey, label="cylinders at the best start")
    axes.plot([], [], "o", color=grey, label="tool at the best start")
    axes.plot([], [], lw=1.5, color="0.25", label="links at the best start (dark)")
    axes.set_aspect("equal", adjustable="datalim")
    across, up = (f"world {a} (m)" for a in robot.task_axes[:2])
    beside = {"loc": "upper left", "bbox_to_anchor": (1.02, 1), "fontsize": 8}  # off the machine
    return _labelled(figure, title, (up,), across, beside)


def cycle_figure(study: CycleStudy, title: str):
    """Every stroke over one cycle, each strategy's first cycle and the per-segment plan's
    best motions; below, the strategies' velocities (its caption says the encodings)."""
    plt = pyplot()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    actuators = study.robot.actuators
    offsets = study.cycle.chain().offsets
    styles = {"free": "-", "periodic": "--"}
    colours = {a.name: f"C{row}" for row, a in enumerate(actuators)}
    tops, bottoms = _by_unit(top, actuators), _by_unit(bottom, actuators)
    # the curves carry no labels: one key, by colour and by line style, names them all
    for name, whole in study.firsts.items():
        t, style = whole.t[0], styles.get(name, "-")
        for row, actuator in enumerate(actuators):
            width = 2.0 if actuator.name in study.held else 1.0
            colour = colours[actuator.name]
            tops[row].plot(t, whole.x[0, :, row], style, lw=width, color=colour)
            bottoms[row].plot(t, whole.x_dot[0, :, row], style, lw=1.0, color=colour)
    for offset, motion in zip(offsets, study.plan.segment_motions):
        if motion is None:
            continue
        for row, actuator in enumerate(actuators):
            colour = colours[actuator.name]
            tops[row].plot(motion.t[0] + offset, motion.x[0, :, row], ":", lw=1.2, color=colour)
    for row, actuator in enumerate(actuators):
        for bound in (actuator.lower, actuator.upper):
            if np.isfinite(bound):
                dashes = limit_dashes(row, len(actuators))
                tops[row].axhline(bound, ls=dashes, lw=0.6, color=colours[actuator.name], alpha=0.5)
    for axes in (top, bottom):
        for corner in offsets[1:-1]:
            axes.axvline(corner, color="k", lw=0.6, alpha=0.4)
    above = {"ha": "center", "va": "bottom", "transform": top.get_xaxis_transform(), "fontsize": 9}
    for start, end, segment in zip(offsets[:-1], offsets[1:], study.cycle.segments):
        top.text((start + end) / 2, 1.01, segment.name, **above)
    from matplotlib.lines import Line2D

    key = [Line2D([], [], color=colours.get(a.name), label=a.name) for a in actuators]
    key += [
        Line2D([], [], ls=style, color="k", label=label)
        for style, label in (("-", "free"), ("--", "drift-free"), (":", "per-segment plan"))
    ]
    key.append(Line2D([], [], ls="--", lw=0.6, color="0.5", label="stroke limits"))
    twinned = any(a is not top for a in tops)
    anchor = (1.12, 1.0) if twinned else (1.01, 1.0)  # beside the angles' axis, where drawn
    top.legend(handles=key, loc="upper left", bbox_to_anchor=anchor, fontsize=8)
    lengths = [a for a in actuators if not a.rotary] or list(actuators)
    angles = [a for a in actuators if a.rotary] or list(actuators)
    labels = (f"stroke x ({unit(lengths)})", f"velocity ẋ ({unit(lengths, rate='/s')})")
    _labelled(figure, title, labels, legend={}, pad=16)  # above the segments' names
    right = (f"stroke x ({unit(angles)})", f"velocity ẋ ({unit(angles, rate='/s')})")
    for axes, drawn, label in zip((top, bottom), (tops, bottoms), right):
        _twin_label(axes, drawn, label)
    figure.tight_layout()  # room for the angles' labels on the right
    return figure


def drift_figure(study: CycleStudy, title: str):
    """Each actuator's |drift| per cycle against cycle number, per strategy (log scale, a drift
    below `redundancy.planning.cycles.ROUNDING` drawn at it); below, each held actuator's start
    of each cycle less its first, and a stroke end those starts pass, dashed."""
    from redundancy.planning.cycles import ROUNDING, SETTLED

    plt = pyplot()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    actuators = study.robot.actuators
    held = [actuators[name] for name in study.held]
    markers = {"free": "o-", "periodic": "s--"}
    for name, repetition in study.repetitions.items():
        cycles = np.arange(1, repetition.cycles + 1)
        drift = np.maximum(np.abs(repetition.drift), ROUNDING)
        marker = markers.get(name, "o-")
        for j, moved in enumerate(actuators.names):  # an actuator's colour in every strategy
            shown = f"{moved}, {name}"
            top.semilogy(cycles, drift[:, j], marker, ms=3, lw=1, color=f"C{j}", label=shown)
        for actuator, start in zip(held, repetition.held_values.T):
            shown = f"{actuator.name}, {name}, from {start[0]:.4f} {actuator.unit}"
            change, colour = start - start[0], f"C{actuators.names.index(actuator.name)}"
            cycles = np.arange(repetition.cycles + 1)
            bottom.plot(cycles, change, marker, ms=3, color=colour, label=shown)
            for end in (actuator.lower, actuator.upper):  # a stroke end the starts pass
                reach = end - start[0]
                if np.isfinite(reach) and np.any(np.sign(reach) * (change - reach) > 0):
                    stroke = f"{actuator.name}'s stroke end ({name})"
                    bottom.axhline(reach, ls="--", lw=0.8, color=colour, label=stroke)
    top.axhline(SETTLED, ls=":", color="k", lw=0.8, label=f"closed: {SETTLED:g}")
    top.set_ylim(bottom=ROUNDING / 2)
    # the change, not the value: its scale is the drift's, however far the stroke's ends are
    bottom.ticklabel_format(axis="y", useOffset=False)
    bottom.xaxis.get_major_locator().set_params(integer=True)
    names = " and ".join(study.held)
    labels = (
        f"|drift| per cycle ({unit(actuators)})",
        f"{names} at the cycle's start, change ({unit(held)})",
    )
    return _labelled(figure, title, labels, "cycle")


def return_map_figure(mapped: ReturnMap, title: str, held_unit: str = "m"):
    """The return map P of the held actuator at the cycle's start: above, P(v) against the
    diagonal (dashed); below, the drift per cycle P(v) − v. The fixed points are the limit
    cycles (filled where stable, |P'| < 1); samples whose cycle passes a stroke are hollow.
    ``held_unit`` is the held actuator's unit."""
    plt = pyplot()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(6.5, 7), sharex=True)
    v, p = mapped.values, mapped.following
    outside = ~mapped.within & np.isfinite(p)
    for axes, values, label in ((top, p, "P(v): one cycle later"), (bottom, p - v, "P(v) − v")):
        axes.plot(v, values, "-", color="C0", lw=1, label=label)
        for kept, fill, words in (
            (mapped.within, "C0", "keeps the strokes"),
            (outside, "none", "passes a stroke"),
        ):
            axes.plot(v[kept], values[kept], "o", ms=4, mfc=fill, color="C0", label=words)
        for value, slope, _ in mapped.fixed_points:
            stable = abs(slope) < 1
            axes.plot(
                value,
                value if axes is top else 0.0,
                "*",
                ms=12,
                color="C3",
                mfc="C3" if stable else "none",
                label=f"limit cycle {value:.4g} {held_unit} (P' = {slope:.2f})",
            )
    top.plot(v, v, "k--", lw=0.8)
    bottom.axhline(0.0, color="k", ls="--", lw=0.8)
    labels = (f"{mapped.held} one cycle later ({held_unit})", f"drift per cycle ({held_unit})")
    return _labelled(figure, title, labels, f"{mapped.held} at the cycle's start ({held_unit})")


def cycle_figures(study: CycleStudy) -> dict:
    """The cycle's figures by file name: strokes over the cycle, drift, return map."""
    figures = {
        "cycle_strokes.png": cycle_figure(
            study, f"Strokes over the cycle {study.cycle.name!r}: strategies and per-segment plan"
        )
    }
    if study.repetitions:
        figures["cycle_drift.png"] = drift_figure(
            study, f"Drift over {study.cycles} cycles, {study.objective.name} objective"
        )
    if study.map is not None:
        figures["cycle_return_map.png"] = return_map_figure(
            study.map,
            f"Return map of {study.map.held}: the free {study.objective.name} law",
            study.robot.actuators[study.map.held].unit,
        )
    return figures


def write_cycle_figures(study: CycleStudy, folder: Path) -> list[Path]:
    """Write the cycle's figures into ``folder``; return their paths."""
    return write_pngs(cycle_figures(study), folder)


def write_pngs(figures: dict, folder: Path, dpi: float = DPI) -> list[Path]:
    """Write each figure (by file name) into ``folder`` as a PNG at ``dpi``, through its Agg
    canvas, and close them all, a write that failed too; return their paths. Through the
    canvas: `savefig` would draw it once more, to redo the layout its `tight_layout` already
    fixed; the files are the same. At zlib's
    fastest level (`PNG_COMPRESSION`) a figure is written in two thirds of the time PIL's
    default level takes, into a file about a quarter larger."""
    plt = pyplot()
    paths = []
    try:
        for filename, figure in figures.items():
            path = folder / filename
            figure.set_dpi(dpi)
            write = partial(figure.canvas.print_png, pil_kwargs={"compress_level": PNG_COMPRESSION})
            write_atomically(path, write)
            paths.append(path)
    finally:  # all of them, a write that failed too: pyplot would keep them for the process
        for figure in figures.values():
            plt.close(figure)
    return paths
