"""The ``redundancy`` command line.

Every failure a user can cause ends in one line on stderr naming the problem, and exit status 2;
an interrupt ends with status 130, a termination (SIGTERM) with 143 (`redundancy.study.signals`),
anything else (a bug) with one "internal error" line and status 1. None prints a traceback. The
outputs appear all together or not at all (`redundancy.study.output`). Progress bars are drawn
only on a terminal.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import ipaddress
import json
import math
import os
import shutil
import signal
import socket
import sys
import unicodedata
import warnings
from dataclasses import replace
from functools import partial
from importlib.metadata import version
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from redundancy.errors import InvalidInputError, RedundancyError, prefixed
from redundancy.model.loading import bundled_robots, load_robot
from redundancy.model.robot import Robot
from redundancy.model.values import MAX_PAYLOAD
from redundancy.planning.angles import task_labels, task_robot
from redundancy.planning.cycles import CYCLES
from redundancy.planning.ik import (
    assembly_branches,
    check_path,
    configuration_at,
    named_values,
)
from redundancy.planning.integrate import Trajectory, simulate
from redundancy.planning.starts import (
    MAX_SAMPLES,
    METHODS,
    default_start,
    held_actuators,
    improved_start,
)
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.limits import amount
from redundancy.resolution.objectives import OBJECTIVES, Objective, objective
from redundancy.resolution.state import actuator_space
from redundancy.study.background import Background
from redundancy.study.check import check, held_problems, span, task_point
from redundancy.study.cycles import CHOICES, run_cycle
from redundancy.study.families import read_family
from redundancy.study.maps import (
    CONNECT_TIMEOUT,
    connect,
    design_map,
    local_workers,
    summary,
)
from redundancy.study.output import OutputFolder, writable
from redundancy.study.signals import Terminated, announce, caught, received
from redundancy.study.signals import written as committed  # the outputs committed whole
from redundancy.study.study import (
    STUDY_CYCLES,
    cycle_section,
    run_study,
    study_searches,
    write_report,
)
from redundancy.viz.map_figures import write_map_figures
from redundancy.viz.playback import (
    export_html,
    play,
    task_points,
    write_cycle_playbacks,
    write_playbacks,
)
from redundancy.viz.plots import write_cycle_figures, write_figures
from redundancy.viz.report import write_index
from redundancy.viz.series import write_series
from redundancy.viz.server import LOCALHOST
from redundancy.viz.tables import check_table, cycle_table, joint_lines, study_table


def describe(robot: Robot) -> str:
    """A summary of a robot: joints, actuators and strokes (mm, degrees), mass, and at
    mid-range (every joint halfway between its limits) x, y and, where the robot has masses,
    M_H (n, n) in kg and the forces F_H = N_H holding still (n,) in N (of a rotary actuator
    kg·m or kg·m², and N·m)."""
    task = " + ".join([robot.task_axes, *task_labels(robot)[len(robot.task_axes) :]])
    lines = [f"{robot.name}: n = {robot.n} joints, task = tool {task} (m = {robot.m})"]
    lines += [*joint_lines(robot), "actuators:"]
    for actuator in robot.actuators:
        stroke = span(actuator.lower, actuator.upper, actuator.unit)
        lines.append(
            f"  {actuator.name:<8} {type(actuator).__name__:<15} on {actuator.joint:<18} "
            f"stroke {stroke}"
        )
    lower, upper = robot.span
    q = (lower + upper) / 2  # mid-range
    space = actuator_space(robot, q)
    if robot.kinematic_only:
        lines.append(f"mass: none on links {', '.join(robot.massless_links)} (kinematic only)")
    else:
        masses = [inertia.mass for inertia in robot.model.inertias]
        lines.append(f"mass: {sum(masses):.1f} kg, of which payload {robot.payload:.1f} kg")
    joints = [amount(v, "rad" if r else "m") for v, r in zip(q, robot.rotary_joints)]
    x = [amount(v, a.unit) for v, a in zip(space.x[0], robot.actuators)]
    lines.append(
        f"at mid-range q = [{', '.join(joints)}]: x = [{', '.join(x)}], "
        f"y = {task_point(robot, space.y[0])}"
    )
    if not robot.kinematic_only:
        rotary = [a.name for a in robot.actuators if a.rotary]
        named = ", ".join(rotary)
        inertia, force = (
            ("kg", "N")
            if not rotary
            else ("kg·m²", "N·m")
            if len(rotary) == robot.n
            else (f"kg; kg·m in a row or column of {named}, kg·m² in both", f"N; N·m for {named}")
        )
        held = np.round(space.forces(np.zeros_like(space.x))[0], 4) + 0.0  # no −0 printed
        with np.printoptions(precision=4, suppress=True):
            lines.append(f"M_H ({inertia}) =\n{space.M_H[0]}")
            lines.append(f"F_H holding still ({force}) = {held}")
    return "\n".join(lines)


def bounded(convert: type, lower: float, upper: float, what: str, unit: str = ""):
    """An argument type: the text ``convert``ed (int or float) within [lower, upper] (``unit``);
    otherwise one line, the text and ``what`` it must be (Python's digit separators refused)."""

    def parse(text: str):
        try:
            value = convert(text) if "_" not in text else math.nan
        except ValueError:
            value = math.nan
        if not lower <= value <= upper:
            raise argparse.ArgumentTypeError(
                f"{text!r} must be {what} within [{lower:,g}, {upper:,g}]{unit}"
            )
        return value

    return parse


def listen_address(text: str) -> str:
    """An IP address of this machine to serve a page on (one a socket can be bound to)."""
    try:
        address = ipaddress.ip_address(text)
        family = socket.AF_INET6 if address.version == 6 else socket.AF_INET
        with socket.socket(family) as probe:
            probe.bind((str(address), 0))
    except (ValueError, OSError):
        raise argparse.ArgumentTypeError(
            f"{text!r} must be an IP address of this machine, e.g. 127.0.0.1 (the default) or "
            "0.0.0.0 (every interface)"
        ) from None
    return str(address)


def start_values(text: str) -> dict[str, float]:
    """``NAME=V[,NAME=V]``: held actuators' start values (m, or rad for a rotary actuator)."""
    found: dict[str, float] = {}
    for item in text.split(","):
        name, equals, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not equals or not name.strip() or not math.isfinite(number) or name in found:
            raise argparse.ArgumentTypeError(
                f"{text!r} must be NAME=V[,NAME=V] with distinct actuator names and finite "
                "values (m, rad for a rotary actuator), e.g. x3=0.6"
            )
        found[name.strip()] = number
    return found


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a bad argument in one line, without the usage block."""

    def error(self, message: str):  # type: ignore[override]
        print(f"{self.prog}: error: {message}; see {self.prog} --help", file=sys.stderr)
        sys.exit(2)


class Help(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Help that shows each option's default (where it has one) and the example as written."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False) or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def _robot(args: argparse.Namespace) -> Robot:
    """The robot of the options --robot, --payload and --hydraulics."""
    return load_robot(args.robot, payload=args.payload, hydraulics=args.hydraulics)


def _not_an_input(path: str, option: str, robot: Robot, cycle: WorkCycle, args) -> None:
    """Check that ``path`` (of ``option``, a file the command writes) is none of the files the
    command reads: the robot's URDF and TOML, the task file, a hydraulics file (where it was,
    the command overwrote it); one line naming it otherwise."""
    read = {
        "URDF": robot.urdf,
        "robot file": robot.actuators.source,
        "task file": cycle.source,
        "hydraulics file": args.hydraulics,
    }
    for what, source in read.items():
        found = source and Path(source).is_file() and Path(path).is_file()
        if found and os.path.samefile(source, path):
            raise InvalidInputError(
                f"{option} {path} is the {what} this command reads; give another path"
            )


def _load_task(robot: Robot, path: str | None) -> tuple[Robot, WorkCycle]:
    """The task file's work cycle and the robot it is read on (with the tool's angle as a task
    coordinate where the task asks for it)."""
    if path is None:
        if robot.task_file is None:
            raise InvalidInputError(f"{robot.name} ships no task; give one with --task FILE")
        path = str(robot.task_file)
    cycle = WorkCycle.from_toml(path, dimension=robot.m)
    return task_robot(robot, cycle), cycle


def _holdable(robot: Robot, cycle: WorkCycle, sampled: bool = True) -> None:
    """Refuse a task whose held actuators cannot be held, in the first line of `held_problems`."""
    if problems := held_problems(robot, cycle, sampled):
        raise InvalidInputError(problems[0])


def _describe_command(args: argparse.Namespace) -> None:
    robot = _robot(args)
    if robot.task_file is not None:  # read on its task: the tool's angle may be a coordinate
        try:
            robot = _load_task(robot, None)[0]
        except RedundancyError as error:  # the robot is described all the same
            warnings.warn(f"its task is not read, {error}", stacklevel=1)
    print(describe(robot))


def _check_command(args: argparse.Namespace) -> int:
    """The one-screen check of a robot (and its task); status 2 where something blocks a
    study."""
    robot, cycle = _robot(args), None
    if args.task is not None or robot.task_file is not None:
        robot, cycle = _load_task(robot, args.task)
    found = check(robot, cycle)
    print(check_table(found))
    return 2 if found.blocking() else 0


def _robots_command(args: argparse.Namespace) -> None:
    for name in bundled_robots():
        with warnings.catch_warnings():  # the list names each robot's actuators itself
            warnings.simplefilter("ignore")
            robot = load_robot(name)
        actuators = ", ".join(robot.actuators.names)
        print(f"{name:<16} n = {robot.n}, m = {robot.m}, actuators: {actuators}")


def _planned_command(args: argparse.Namespace) -> None:
    """The study and the cycle commands: ``args.plan`` (`_study`, `_cycle`) gives (result, figure
    paths, playback paths, time series paths); the report and index page are written beside
    them, all committed together, and what was written is listed."""
    with OutputFolder(args.out) as out:  # committed only if everything below succeeds
        report = out / "report.json" if args.json is None else out.beside(Path(args.json), "--json")
        robot, cycle = _load_task(_robot(args), args.task)
        if args.json is not None:
            _not_an_input(args.json, "--json", robot, cycle, args)
        _holdable(robot, cycle)
        checked = None if args.check is None else tuple(args.check.split(","))
        with prefixed(f"--check {args.check}"):
            robot.actuators.rows(checked or ())
        options = dict(
            samples=args.samples, checked=checked, method=args.method, circuit=args.circuit_limits
        )
        result, figures, playbacks, series = args.plan(args, out.staging, robot, cycle, options)
        write_report(result, report)
        written = {"figures": figures, "time series (CSV)": series, "playbacks": playbacks}
        write_index(out.staging, report)
    print(f"start here: {out.target / 'index.html'}")
    print(f"report: {args.json or out.target / 'report.json'}")
    for label, paths in written.items():
        print(f"{label}: {', '.join(str(out.final(p)) for p in paths)}")


def _study(args: argparse.Namespace, folder: Path, robot, cycle, options) -> tuple:
    from tqdm import tqdm

    tqdm.monitor_interval = 0  # no monitor thread: with a thread running, `Background` cannot fork

    chosen = ("velocity", "energy") if args.objective == "both" else (args.objective,)
    if robot.kinematic_only and args.objective == "both":
        chosen = ("velocity",)
        warnings.warn(
            f"{robot.name} is kinematic only: the study leaves out what needs masses (the "
            "energy objective, the M_H-weighted law, peak ẋᵀM_Hẋ); give the links "
            "<inertial>s for them",
            stacklevel=1,
        )
    objectives = tuple(objective(name) for name in chosen)
    bound = args.energy_bound
    # the improved searches first: the cycle section's per-segment plan is the first objective's
    searches = study_searches(robot, cycle, objectives, **options, energy_bound=bound)

    def section() -> tuple:
        """The cycle section and its figures and playbacks: (cycle study or None, why none,
        figure paths, playback paths)."""
        found, skipped = cycle_section(
            robot, cycle, objectives[0], args.cycles, **options, segments=searches.first()
        )
        if found is None:
            return None, skipped, [], []
        return found, None, write_cycle_figures(found, folder), write_cycle_playbacks(found, folder)

    # the cycle section and its outputs are computed in a second process meanwhile
    with Background(section) as pending:
        study = run_study(
            robot,
            cycle,
            objectives,
            **options,
            bound=not args.no_bound,
            progress=args.progress,
            energy_bound=bound,
            cycles=0,
            searches=searches,
        )
        # the figures only read numbers the study has computed: drawn in a third process
        # while this one writes the playbacks and, once the cycle section ends, the series
        with Background(write_figures, study, folder) as drawing:
            playbacks = write_playbacks(study, folder)
            with tqdm(total=1, desc="cycle section", disable=not args.progress) as waiting:
                cycle_study, skipped, cycle_figures, cycle_playbacks = pending.result()
                waiting.update()
            study = replace(study, cycle_study=cycle_study, cycle_skipped=skipped)
            series = write_series(study, folder)
            figures = drawing.result()
    print(study_table(study))
    return study, figures + cycle_figures, playbacks + cycle_playbacks, series


def _cycle(args: argparse.Namespace, folder: Path, robot, cycle, options) -> tuple:
    study = run_cycle(
        robot,
        cycle,
        objective(args.objective),
        args.cycles,
        args.strategy,
        **options,
        speed=args.gap_speed,
        progress=args.progress,
    )
    print(cycle_table(study))
    figures, playbacks = write_cycle_figures(study, folder), write_cycle_playbacks(study, folder)
    return study, figures, playbacks, write_series(study, folder)


def _play_motion(
    robot: Robot, cycle: WorkCycle, segment: Segment, chosen: Objective, args: argparse.Namespace
) -> tuple[Trajectory, str]:
    """The motion ``play`` shows, from the start the options choose, and that start in words."""
    _holdable(robot, cycle, sampled=args.start is None and args.x3init is None)
    held = held_actuators(robot, cycle)
    if args.best:
        search = improved_start(robot, segment, chosen, held, args.samples, method=args.method)
        motion = search.motion()  # the best; says so when no start keeps the limits
        values = search.best.values  # type: ignore[union-attr]
        return motion, f"best of {search.simulations} starts, {named_values(robot, held, values)}"
    if args.start is None and args.x3init is None:
        values, q = default_start(robot, segment, held)
        label = f"default start, {named_values(robot, held, values)}"
        return simulate(robot, chosen.resolver, segment, q[None]), label
    option = "--start" if args.x3init is None else "--x3init"
    given = args.start if args.x3init is None else {held[0]: args.x3init}
    if set(given) != set(held):
        raise InvalidInputError(
            f"{option} sets {', '.join(given)}; task {cycle.name!r} holds {list(held)}: "
            f"give each, --start {','.join(f'{h}=V' for h in held)} (m, rad)"
        )
    for name, value in given.items():
        stroke = robot.actuators[name]
        if not stroke.lower <= value <= stroke.upper:
            shown = f"{name}={value:g}" if option == "--start" else f"{value:g}"
            # a length a thousand times one inside the stroke: given in mm
            in_mm = stroke.unit == "m" and stroke.lower <= value / 1000 <= stroke.upper
            raise InvalidInputError(
                f"{option} {shown} is outside the stroke of {name}: "
                f"{amount(value, stroke.unit) if np.isfinite(value) else value}, stroke "
                f"{span(stroke.lower, stroke.upper, stroke.unit)}"
                + ("; did you give mm? the value is in m" if in_mm else "")
            )
    values = [given[h] for h in held]
    configurations = assembly_branches(robot, segment.start, held, values)
    if not len(configurations):  # says by how much the start is missed
        configuration_at(robot, segment.start, dict(zip(held, values)))
    q, branches = configurations[0], len(configurations)  # the pick of inverse kinematics first
    label = named_values(robot, held, values)
    if branches > 1:  # the start is the branch inverse kinematics picks; the search's may differ
        label += (
            f", one of {branches} start configurations there (assembly branches), the one "
            "inverse kinematics picks first; --best plays the improved start's"
        )
    return simulate(robot, chosen.resolver, segment, q[None]), label


def _play_command(args: argparse.Namespace) -> None:
    html = None if args.html is None else writable(args.html, "--html")
    robot, cycle = _load_task(_robot(args), args.task)
    if html is not None:
        _not_an_input(args.html, "--html", robot, cycle, args)
    segment = cycle.segments[0] if args.segment is None else cycle[args.segment]
    chosen = objective(args.objective)
    check_path(robot, segment)
    motion, start = _play_motion(robot, cycle, segment, chosen, args)
    points = task_points(cycle)
    strategy = f"{chosen.name} objective, {start}"  # the pages' headings, live or exported
    heading = f"segment {segment.name}, {strategy}"
    if html is not None:
        page = export_html(motion, html, points, strategy)
        print(f"playback: {page} ({heading})")
        return
    # Ctrl-C and termination both stop the loop (`main` catches them, even where a shell started
    # the command with SIGINT ignored), and play's clean-up takes the meshcat server down with it.
    play(
        motion,
        points,
        lambda url: print(f"{heading}: open {url} (Ctrl-C stops)", flush=True),
        args.listen,
        strategy,
    )


def _map_command(args: argparse.Namespace) -> None:
    family = read_family(args.family)
    if args.workers is not None:  # more than the memory holds: refused before any output
        local_workers(args.workers, f"--workers {args.workers}")
    target = Path(Path("maps") / Path(args.family).stem if args.out is None else args.out)
    with OutputFolder(target) as out:  # committed only if everything below succeeds
        store = target.parent / f".{target.name}.chunks"  # finished chunks, kept for a rerun
        with (
            contextlib.nullcontext()
            if args.scheduler is None
            else connect(args.scheduler, args.timeout)
        ) as client:
            table = design_map(family, client, args.workers, store, progress=args.progress)
        line = summary(table, family)
        print(line)
        table.to_parquet(out / "map.parquet")
        outline = {
            "name": family.name,
            "objectives": list(family.objectives),
            "summary": line,
            "problems": len(family),
            "rows": len(table),
        }
        (out / "summary.json").write_text(json.dumps(outline) + "\n")
        figures = [out.final(p) for p in write_map_figures(table, family, out.staging)]
        write_index(out.staging)
    shutil.rmtree(store, ignore_errors=True)
    print(f"start here: {out.target / 'index.html'}")
    print(f"map: {out.target / 'map.parquet'} ({len(table)} rows)")
    print(f"figures: {', '.join(str(p) for p in figures)}")


def parser() -> argparse.ArgumentParser:
    """The command line: each command's options, from the parents they share."""
    whole = partial(bounded, int, what="a whole number")
    robot = argparse.ArgumentParser(add_help=False)
    robot.add_argument("--robot", default="hiab031", help="bundled robot, or robot.toml or .urdf")
    mass = bounded(float, 0, MAX_PAYLOAD, "a mass", " kg")
    robot.add_argument("--payload", type=mass, help="payload at the tool, kg (robot's)")
    robot.add_argument("--hydraulics", metavar="FILE", help="TOML file with a [hydraulics] table")
    task = argparse.ArgumentParser(add_help=False)
    task.add_argument("--task", help="task file (TOML); default: the robot's own")
    sampled = argparse.ArgumentParser(add_help=False)
    sampled.add_argument(
        "--samples",
        type=whole(1, MAX_SAMPLES),
        default=100,
        help="starts of the sweep over the held strokes (--method sweep, which several held "
        "actuators always take; play reads it with --best only)",
    )
    sampled.add_argument(
        "--method",
        choices=METHODS,
        help="the improved start's search (default: fast with one held actuator)",
    )
    search = argparse.ArgumentParser(add_help=False, parents=[sampled])
    search.add_argument(
        "--check", help="comma-separated actuators whose limits count (all; the paper: x1,x2)"
    )
    search.add_argument(
        "--circuit-limits",
        action="store_true",
        help="the hydraulic circuit's limits (pressure, pump flow, speeds) count like strokes",
    )
    quiet = argparse.ArgumentParser(add_help=False)
    quiet.add_argument("--quiet", action="store_true", help="no progress bar")
    written = argparse.ArgumentParser(add_help=False, parents=[quiet])
    written.add_argument("--json", help="report path (default: OUT/report.json)")
    minimised = argparse.ArgumentParser(add_help=False)
    minimise = "what to minimise"
    minimised.add_argument(
        "--objective", choices=list(OBJECTIVES), default="velocity", help=minimise
    )
    main = OneLineParser(
        prog="redundancy",
        description="Redundancy resolution of hydraulic manipulators in actuator coordinates.",
    )
    main.add_argument("--version", action="version", version=f"%(prog)s {version('redundancy')}")
    commands = main.add_subparsers(dest="command", required=True)

    def command(name, run, help, example, parents=(), **defaults) -> argparse.ArgumentParser:
        found = commands.add_parser(
            name,
            help=help,
            description=help,
            parents=parents,
            formatter_class=Help,
            epilog=f"example:\n  redundancy {name} {example}".rstrip(),
        )
        found.set_defaults(run=run, parser=found, **defaults)
        return found

    command("robots", _robots_command, "list the bundled robots", "")
    command("describe", _describe_command, "summarise a robot", "--robot excavator", [robot])
    command(
        "check",
        _check_command,
        "check a new robot for a study: strokes, singular A, masses, meshes, task",
        "--robot path/to/robot.toml",
        [robot, task],
    )
    study = command(
        "study",
        _planned_command,
        "the paper's study: improved initial configurations and strategies compared",
        "--objective velocity --check x1,x2 --out results",
        [robot, task, search, written],
        plan=_study,
    )
    study.add_argument(
        "--objective",
        choices=[*OBJECTIVES, "both"],
        default="both",
        help=f"{minimise}; both: the paper's velocity and energy",
    )
    study.add_argument(
        "--no-bound",
        action="store_true",
        help="leave out the min-max bound and the gaps to it (on a robot of many joints it may "
        "take minutes per segment)",
    )
    study.add_argument(
        "--energy-bound",
        action="store_true",
        help="also the energy bound of each segment under LS and CP (seconds per segment)",
    )
    study.add_argument(
        "--cycles",
        type=whole(0, 10_000),
        default=STUDY_CYCLES,
        help="the cycle section repeats the task this many times (0: no cycle section)",
    )
    study.add_argument("--out", default="results", help="output folder (figures, report)")
    play = command(
        "play",
        _play_command,
        "play one motion in meshcat: live in a browser, or as an HTML page",
        "--segment 1-2 --best",
        [robot, task, minimised, sampled],
    )
    play.add_argument("--segment", help="segment to play (default: the task's first)")
    start = play.add_mutually_exclusive_group()
    start.add_argument(
        "--x3init", type=float, metavar="V", help="start with the one held actuator at V, m"
    )
    start.add_argument(
        "--start",
        type=start_values,
        metavar="NAME=V[,NAME=V]",
        help="start with each held actuator at its value, m (rad for a rotary one)",
    )
    start.add_argument("--best", action="store_true", help="start from the improved start")
    play.add_argument("--html", metavar="FILE", help="write a page instead of serving one")
    play.add_argument(
        "--listen",
        metavar="ADDRESS",
        type=listen_address,
        default=LOCALHOST,
        help="serve the page on ADDRESS (0.0.0.0: on every network this machine is on)",
    )
    design = command(
        "map",
        _map_command,
        "a design map: a family of planning problems solved on Dask, to Parquet",
        "workspace.toml --workers 2",
        [quiet],
    )
    design.add_argument("family", help="map file (TOML; schema in docs/maps.md)")
    where = design.add_mutually_exclusive_group()
    where.add_argument("--workers", type=whole(1, 4096), help="local worker processes (cores)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a Dask cluster: tcp://HOST:8786")
    design.add_argument(
        "--timeout",
        type=bounded(float, 1e-3, 3600, "seconds"),
        default=CONNECT_TIMEOUT,
        help="seconds the scheduler has to answer",
    )
    design.add_argument("--out", help="output folder (default: maps/<map file name>)")
    cycle = command(
        "cycle",
        _planned_command,
        "the work cycle as a machine runs it: whole-cycle plan, repetition, drift",
        "--strategy periodic --cycles 50",
        [robot, task, search, written, minimised],
        plan=_cycle,
    )
    cycle.add_argument("--cycles", type=whole(1, 10_000), default=CYCLES, help="cycles in a row")
    cycle.add_argument(
        "--strategy",
        choices=CHOICES,
        default="both",
        help="free: the objective's law from the whole-cycle improved start; periodic: the "
        "drift-free periodic optimum",
    )
    cycle.add_argument(
        "--gap-speed",
        type=bounded(float, 1e-3, 10, "a speed", " (m/s or rad/s)"),
        metavar="V",
        help="the held actuator's speed in the corners' self-motions (default: its cylinder's "
        "maximum, else 0.1)",
    )
    cycle.add_argument("--out", default="cycle_results", help="output folder")
    return main


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings (e.g. joints driven directly for want of declarations) as one line each, each
    once: a robot loaded again (a design map's variants) says the same again, and a library's
    `warnings.catch_warnings` resets what Python's filters remember as said."""
    text = f"redundancy: note: {message}"
    if text not in _said:
        _said.add(text)
        print(text, file=sys.stderr)


_said: set[str] = set()  # the notes this command has printed


class _Output:
    """Standard output that turns into /dev/null once its reader has gone (``redundancy
    robots | head -1``): a closed pipe never stops a run half-way or ends it with an error."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        self._unless_gone(self.stream.write, text)
        return len(text)

    def flush(self) -> None:
        self._unless_gone(self.stream.flush)

    def _unless_gone(self, call, *args) -> None:
        """``call(*args)``; where the reader has gone, what is written from now on, and what is
        still buffered, goes to /dev/null. Any other failure (a full disk) does too, so that
        the interpreter's last flush fails no second time, and is raised naming the stream."""
        try:
            call(*args)
        except OSError as error:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self.stream.fileno())
            os.close(null)
            if not isinstance(error, BrokenPipeError):
                raise OSError(error.errno, error.strerror, "standard output") from None

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


def one_line(text: str) -> str:
    """``text`` with its control characters (a newline, a terminal's escape) written as
    escapes: a message stays one line and shows what a value holds."""
    return "".join(repr(c)[1:-1] if unicodedata.category(c) == "Cc" else c for c in text)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; exit status 0, 2 for a user's error (one line), 130 / 143 when
    interrupted / terminated, 1 for an internal error (one line with the exception's type)."""
    if sys.stdout is None:  # started with its standard output closed (``>&-``)
        print(
            "redundancy: error: standard output is closed; give it a file or /dev/null",
            file=sys.stderr,
        )
        return 2
    for stream in (sys.stdout, sys.stderr):  # a terminal that cannot show m², ±, ẋ: a '?'
        stream.reconfigure(errors="replace")  # type: ignore[union-attr]
    line = parser()
    args, unknown = line.parse_known_args(argv)
    if unknown:  # said by the command they were given to (or before it: the command line's)
        given = sys.argv[1:] if argv is None else argv
        before = given.index(unknown[0]) < given.index(args.parser.prog.split()[-1])
        (line if before else args.parser).error(f"unrecognized arguments: {' '.join(unknown)}")
    args.progress = not getattr(args, "quiet", True) and sys.stderr.isatty()
    warnings.showwarning = _note
    _said.clear()  # each command says its notes once (main may run again in one process)
    stdout, sys.stdout = sys.stdout, _Output(sys.stdout)
    try:
        # play's loop is stopped by Ctrl-C even where the shell started it as a background job
        with caught(interrupt=args.run is _play_command):
            # the toolkit's matrices are stacks of n × n with n ≤ 7: BLAS threads never speed
            # them up, and their spinning takes the core the study's second process needs
            with threadpool_limits(limits=1, user_api="blas"):
                status = args.run(args)  # a command may end with a status of its own (check: 2)
            sys.stdout.flush()
            if received:  # raised where Python could only ignore it (a weakref callback)
                raise KeyboardInterrupt
    except BaseException as error:
        # a signal decides, even where a library turned its exception into another (an import
        # cut short ends in ImportError)
        if received or isinstance(error, KeyboardInterrupt | Terminated):
            default = signal.SIGTERM if isinstance(error, Terminated) else signal.SIGINT
            status = announce(received[-1] if received else default, sys.stderr.write)
        elif isinstance(error, RedundancyError):
            print(f"redundancy: error: {one_line(str(error))}", file=sys.stderr)
            status = 2
        elif isinstance(error, OSError) and error.errno in (errno.ENOSPC, errno.EDQUOT):
            # the file or stream that could not be written (output.py names a staged one by
            # the path given), else the command's output
            output = getattr(args, "out", None) or getattr(args, "html", None) or "the output"
            where = one_line(str(error.filename or output))
            kept = (
                f"wrote {', '.join(committed)} whole"
                if committed
                else "this run's output was not kept"
            )
            print(
                f"redundancy: error: {where}: {os.strerror(error.errno)}; {kept}", file=sys.stderr
            )
            status = 2
        elif isinstance(error, OSError) and error.errno == errno.ENAMETOOLONG:
            name = one_line(str(error.filename))  # a path given on the command line
            print(f"redundancy: error: {name}: {os.strerror(error.errno)}", file=sys.stderr)
            status = 2
        elif isinstance(error, SystemExit):
            raise
        else:
            text = one_line(f"{type(error).__name__}: {error}")
            print(f"redundancy: internal error: {text}", file=sys.stderr)
            status = 1
    finally:
        sys.stdout = stdout
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
