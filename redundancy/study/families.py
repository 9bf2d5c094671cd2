"""Families of planning problems for design maps, declared in a TOML file.

A problem is one straight segment (`redundancy.planning.tasks.Segment`) on one design of the
robot. A family is the product of its segments and a grid of design parameters, enumerated in a
fixed order (segments outermost, then the grid's parameters in the order written below, the
last varying fastest), so that problem i is the same problem wherever and whenever it is solved.

Segments come from one of two tables::

    [workspace]                 # every segment of one length and direction, its start on a grid
    length = 1.0                # m
    direction = [-1.0, 0.0]     # along the task axes; normalised
    speed = 0.5                 # m/s (default 0.5)
    [workspace.grid]            # per task axis: [from, to, count], or a count alone to span
    x = [0.5, 4.0, 8]           # the reachable workspace's extent along that axis
    z = 6

    [task]                      # or the segments of a task file
    file = "task.toml"          # relative to the map file; default: the robot's own task
    segments = ["1-2"]          # default: every segment of the file

and the design grid from an optional ``[grid]`` table, each key a list of values or
``{from = a, to = b, count = k}``::

    [grid]
    payload = [0, 250, 500]                 # kg at the tool
    speed = [0.25, 0.5]                     # m/s along every segment
    attachment = {actuator = "x1", end = "base", axis = "x", values = [...]}   # m, link frame
    bore = {actuator = "x1", values = [0.07, 0.08]}                            # m (hydraulics)

The rest of the file::

    name = "workspace gain"     # default: the file's name
    robot = "hiab031"           # bundled name, or a robot.toml / URDF path relative to this file
    hydraulics = "circuit.toml" # optional [hydraulics] file, relative to this file
    objectives = ["velocity", "energy"]     # default both
    held = ["x3"]               # default: the task file's, or the last n − m actuators
    chunk = 8                   # problems per chunk of work (default 8)
    bound = false               # also the min-max bound and the improved start's gap to it
    energy = false              # also pump energy and peak flow of the best motions (hydraulics)
    circuit = false             # the circuit's limits (pressures, pump flow, speeds) count like
                                # strokes, so that bores and supplies change what is feasible
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from redundancy.errors import InvalidInputError
from redundancy.model.actuators import ActuatorSet, LinearCylinder
from redundancy.model.loading import bundled_robots, load_robot
from redundancy.model.robot import AXES, Robot
from redundancy.model.values import (
    MAX_PAYLOAD,
    MAX_SPEED,
    coordinates,
    names,
    number,
    read_toml,
    refuse_unknown,
    text,
)
from redundancy.planning.ik import held_indices
from redundancy.planning.starts import held_actuators
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.objectives import OBJECTIVES

KEYS = (
    "name",
    "robot",
    "hydraulics",
    "objectives",
    "held",
    "chunk",
    "bound",
    "energy",
    "circuit",
    "workspace",
    "task",
    "grid",
)  # a map file's keys
WORKSPACE_KEYS = ("length", "direction", "speed", "grid")
TASK_KEYS = ("file", "segments")
PARAMETERS = ("payload", "speed", "attachment", "bore")  # the design grid's keys, in order
RANGE_KEYS = ("from", "to", "count")  # a design parameter's values as a range
DESIGN_KEYS = {
    "attachment": ("actuator", "end", "axis", "values"),
    "bore": ("actuator", "values"),
}  # the keys of the design parameters given as a table
MAX_PROBLEMS = 2_000_000  # problems of one family: its table, held in memory at about 200 bytes
# per row and objective, stays under 1 GB with two objectives; split a larger family
MAX_CHUNK = 10_000
ENDS = ("base", "rod")
WORKSPACE_SAMPLES = 4096  # joint-space samples spanning the reachable workspace's extent


@dataclass(frozen=True)
class Design:
    """One point of the design grid: a value per parameter the grid varies (None elsewhere)."""

    payload: float | None = None
    speed: float | None = None
    attachment: float | None = None
    bore: float | None = None


@dataclass(frozen=True)
class MapFamily:
    """Segments × a design grid (see the module docstring). ``grid`` holds, per parameter it
    varies, its values; ``attachment`` = (actuator, end, axis) and ``bore`` = actuator name
    say what those parameters move."""

    name: str
    robot: str
    hydraulics: str | None
    objectives: tuple[str, ...]
    held: tuple[str, ...]
    segments: tuple[Segment, ...]
    grid: tuple[tuple[str, tuple[float, ...]], ...] = ()
    attachment: tuple[str, str, str] | None = None
    bore: str | None = None
    chunk: int = 8
    bound: bool = False
    energy: bool = False
    circuit: bool = False

    def __len__(self) -> int:
        return len(self.segments) * math.prod(len(v) for _, v in self.grid)

    @property
    def chunks(self) -> int:
        """How many chunks of ``chunk`` problems the family makes."""
        return -(-len(self) // self.chunk)

    def problems(self, chunk: int) -> list[tuple[int, Segment, Design]]:
        """The problems (index, segment, design) of chunk number ``chunk``: problem i is segment
        i // D with design i % D of the D the grid makes, numbered as `itertools.product`
        would (the last parameter fastest), each built alone."""
        sizes = [len(values) for _, values in self.grid]
        designs = math.prod(sizes)
        first = chunk * self.chunk
        found = []
        for i in range(first, min(first + self.chunk, len(self))):
            position = np.unravel_index(i % designs, sizes) if sizes else ()
            values = {key: grid[j] for (key, grid), j in zip(self.grid, position)}
            found.append((i, self.segments[i // designs], Design(**values)))
        return found

    @cached_property
    def fingerprint(self) -> str:
        """A digest of everything the rows depend on: the family (every segment's name, ends,
        path and timing whole) and the robot's files."""
        digest = hashlib.sha256()
        _digest(digest, self)
        for path in _robot_files(self.robot, self.hydraulics):
            digest.update(path.read_bytes())
        return digest.hexdigest()[:16]

    def robot_for(self, design: Design) -> Robot:
        """The robot with ``design``'s payload, attachment and bore (loaded once per process)."""
        return _variant(
            self.robot,
            self.hydraulics,
            design.payload,
            self.attachment,
            design.attachment,
            self.bore,
            design.bore,
        )

    def segment_for(self, segment: Segment, design: Design) -> Segment:
        if design.speed is None:
            return segment
        return Segment(segment.name, segment.start, segment.end, design.speed)


def _digest(digest, value: object) -> None:
    """Feed ``value`` to ``digest``: a dataclass field by field (what its fields are, not what
    it has cached), an array by its type, shape and bytes (whole: its repr would elide a long
    polyline's middle, and cost seconds on a large family), a sequence item by item, anything
    else by its repr."""
    if dataclasses.is_dataclass(value):
        digest.update(type(value).__name__.encode())
        for field in dataclasses.fields(value):
            _digest(digest, getattr(value, field.name))
    elif isinstance(value, np.ndarray):
        digest.update(f"{value.dtype}{value.shape}".encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, list | tuple):
        digest.update(f"{type(value).__name__}{len(value)}".encode())
        for item in value:
            _digest(digest, item)
    else:
        digest.update(repr(value).encode())


def _robot_files(robot: str, hydraulics: str | None) -> list[Path]:
    """The files a robot is read from, bundled or not: its description, its URDF, its task and
    its hydraulics file."""
    loaded = load_robot(robot, hydraulics=hydraulics)
    given = Path(robot)
    description = given if given.is_file() else loaded.urdf.parent / "robot.toml"
    files = [description, loaded.urdf, loaded.task_file, hydraulics]
    return [Path(f) for f in dict.fromkeys(files) if f is not None and Path(f).is_file()]


@lru_cache(maxsize=16)
def _variant(
    robot: str,
    hydraulics: str | None,
    payload: float | None,
    attachment: tuple[str, str, str] | None,
    offset: float | None,
    bore_of: str | None,
    bore: float | None,
) -> Robot:
    """``robot`` with a payload, one attachment coordinate moved to ``offset`` (m, in its link's
    frame) and one cylinder's bore set to ``bore`` (m)."""
    loaded = load_robot(robot, payload=payload, hydraulics=hydraulics)
    if attachment is None and bore_of is None:
        return loaded
    maps = list(loaded.actuators.maps)
    if attachment is not None and offset is not None:
        actuator, end, axis = attachment
        i = loaded.actuators.names.index(actuator)
        cylinder = maps[i]
        assert isinstance(cylinder, LinearCylinder)  # checked when the family was read
        link, point = getattr(cylinder, end)
        moved = point.copy()
        moved[AXES.index(axis)] = offset
        ends = {"base": cylinder.base, "rod": cylinder.rod, end: (link, moved)}
        maps[i] = LinearCylinder(
            cylinder.name,
            cylinder.joint,
            cylinder.lower,
            cylinder.upper,
            ends["base"],
            ends["rod"],
        )
    circuit = loaded.hydraulics
    if bore_of is not None and bore is not None and circuit is not None:
        i = circuit.names.index(bore_of)
        cylinders = list(circuit.cylinders)
        if not cylinders[i].rod < bore:
            raise InvalidInputError(
                f"bore {bore} m of {bore_of} must exceed its rod, {cylinders[i].rod} m"
            )
        cylinders[i] = dataclasses.replace(cylinders[i], bore=bore)
        circuit = dataclasses.replace(circuit, cylinders=tuple(cylinders))
    model = pin.Model(loaded.model)
    return Robot(
        loaded.name,
        model,
        loaded.tool_frame,
        loaded.task_axes,
        ActuatorSet.bind(maps, model),
        loaded.payload,
        loaded.urdf,
        loaded.task_file,
        circuit,
        zero_masses=loaded.zero_masses,
    )


def _values(value: object, where: str, meaning: str, lower: float, upper: float) -> tuple:
    """A list of numbers, or {from, to, count}, as a tuple of floats within [lower, upper]."""
    if isinstance(value, dict):
        refuse_unknown(value, RANGE_KEYS, where)
        start = number(value, "from", where, meaning, lower=lower, upper=upper)
        stop = number(value, "to", where, meaning, lower=lower, upper=upper)
        count = value.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 100_000:
            raise InvalidInputError(f"{where}: count = {count!r} must be a whole number ≥ 1")
        return tuple(float(v) for v in np.linspace(start, stop, count))
    array = coordinates(value, where, None)
    if array.ndim != 1 or not array.size:
        raise InvalidInputError(
            f"{where} = {value!r} gives no values; give a list of numbers or "
            "{from = a, to = b, count = k}"
        )
    if np.any(array < lower) or np.any(array > upper):
        raise InvalidInputError(
            f"{where} = {value!r}: values must be within [{lower:g}, {upper:g}]"
        )
    return tuple(float(v) for v in array)


def _axis_values(value: object, where: str, extent: tuple[float, float]) -> tuple[float, ...]:
    """[from, to, count], or a count over ``extent``, as the grid's coordinates."""
    if isinstance(value, int) and not isinstance(value, bool):
        value = [extent[0], extent[1], value]
    if not (isinstance(value, list) and len(value) == 3):
        raise InvalidInputError(
            f"{where} = {value!r} must be [from, to, count] (m) or a count alone"
        )
    start, stop = coordinates(value[:2], where, None)
    count = value[2]
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 100_000:
        raise InvalidInputError(f"{where}: count {count!r} must be a whole number ≥ 1")
    return tuple(float(v) for v in np.linspace(start, stop, count))


def workspace_extent(robot: Robot) -> np.ndarray:
    """Per task axis, the smallest and largest tool coordinate over `WORKSPACE_SAMPLES` scrambled
    Halton configurations inside the joint limits, (m, 2) in m."""
    from scipy.stats import qmc

    unit = qmc.Halton(d=robot.n, scramble=True, seed=11).random(WORKSPACE_SAMPLES)
    y = robot.task_point(robot.kinematics(robot.lower + (robot.upper - robot.lower) * unit))[0]
    return np.stack([y.min(axis=0), y.max(axis=0)], axis=1)


def _workspace(
    robot: Robot, table: object, where: str
) -> tuple[list[tuple[float, ...]], np.ndarray, float]:
    """The ``[workspace]`` table: the grid's coordinates per task axis, the step from a
    segment's start to its end (m) and the speed along it (m/s)."""
    if not isinstance(table, dict):
        raise InvalidInputError(f"{where}: [workspace] must be a table")
    refuse_unknown(table, WORKSPACE_KEYS, f"{where}: [workspace]")
    length = number(table, "length", where, "m, each segment's length", lower=1e-6, upper=1e3)
    direction = coordinates(table.get("direction"), f"{where}: direction", robot.m)
    if not np.linalg.norm(direction) > 0:
        raise InvalidInputError(f"{where}: direction = {direction.tolist()} must be nonzero")
    speed = number(table, "speed", where, "m/s along each segment", 0.5, 1e-6, MAX_SPEED)
    grid = table.get("grid")
    if not isinstance(grid, dict):
        raise InvalidInputError(
            f"{where}: needs a [workspace.grid] table with one entry per task axis "
            f"({', '.join(robot.task_axes)})"
        )
    unknown = sorted(set(grid) - set(robot.task_axes))
    if unknown:
        raise InvalidInputError(
            f"{where}: [workspace.grid] has {unknown}; task axes: {', '.join(robot.task_axes)}"
        )
    extent = workspace_extent(robot)
    axes = []
    for a, axis in enumerate(robot.task_axes):
        if axis not in grid:
            raise InvalidInputError(f"{where}: [workspace.grid] misses the task axis {axis!r}")
        axes.append(_axis_values(grid[axis], f"{where}: workspace.grid.{axis}", tuple(extent[a])))
    return axes, length * direction / np.linalg.norm(direction), speed


def _workspace_segments(
    axes: list[tuple[float, ...]], step: np.ndarray, speed: float
) -> tuple[Segment, ...]:
    """A segment from every point of the grid ``axes`` to that point + ``step``."""
    return tuple(
        Segment(f"start {i}", np.array(start), np.array(start) + step, speed)
        for i, start in enumerate(itertools.product(*axes))
    )


def _check_size(segments: int, grid: tuple[tuple[str, tuple], ...], where: str) -> None:
    """Refuse a family of more than `MAX_PROBLEMS` problems, counted from its ``segments``
    and the design ``grid``'s sizes before any of them is built."""
    problems = segments * math.prod(len(values) for _, values in grid)
    if problems > MAX_PROBLEMS:
        raise InvalidInputError(
            f"{where}: the family has {problems:,} problems; it must have at most "
            f"{MAX_PROBLEMS:,} (split a larger family)"
        )


def _task_segments(robot: Robot, table: object, folder: Path, where: str):
    if not isinstance(table, dict):
        raise InvalidInputError(f"{where}: [task] must be a table")
    refuse_unknown(table, TASK_KEYS, f"{where}: [task]")
    if "file" in table:
        path = folder / text(table, "file", where, "the task file, relative to the map file")
    elif robot.task_file is not None:
        path = robot.task_file
    else:
        raise InvalidInputError(f"{where}: [task] needs file = ...; {robot.name} has no task")
    cycle = WorkCycle.from_toml(path, dimension=robot.m)
    chosen = names(table, "segments", where, "segments of the task file", (), distinct=True)
    segments = tuple(cycle[s] for s in chosen) if chosen else cycle.segments
    return segments, cycle


def read_family(path: Path | str) -> MapFamily:
    """The family declared in the map file ``path`` (see the module docstring)."""
    path = Path(path)
    data = read_toml(path, "map file")
    where, folder = str(path), path.resolve().parent
    refuse_unknown(data, KEYS, where)
    robot_name = text(data, "robot", where, "bundled name or robot path", "hiab031")
    if not (robot_name in bundled_robots() and not (folder / robot_name).exists()):
        robot_name = str(folder / robot_name)
    hydraulics = text(data, "hydraulics", where, "a [hydraulics] file", None)
    hydraulics = None if hydraulics is None else str(folder / hydraulics)
    robot = load_robot(robot_name, hydraulics=hydraulics)
    objectives = names(
        data,
        "objectives",
        where,
        f"objectives: {', '.join(OBJECTIVES)}",
        ("velocity", "energy"),
        distinct=True,
    )
    for name in objectives:
        if name not in OBJECTIVES:
            raise InvalidInputError(
                f"{where}: objective {name!r} unknown; objectives: {', '.join(OBJECTIVES)}"
            )
    if not objectives:
        raise InvalidInputError(f"{where}: objectives = [] names none; give at least one")
    flags = {}
    for key in ("bound", "energy", "circuit"):
        flags[key] = data.get(key, False)
        if not isinstance(flags[key], bool):
            raise InvalidInputError(f"{where}: {key} = {flags[key]!r} must be true or false")
    if flags["energy"] or flags["circuit"]:
        robot.circuit()  # says how to declare one
    if ("workspace" in data) == ("task" in data):
        raise InvalidInputError(f"{where}: give the segments by one table, [workspace] or [task]")
    held = names(data, "held", where, "actuators the search holds", (), distinct=True)
    grid, attachment, bore = _grid(robot, data.get("grid", {}), f"{where}: [grid]")
    if "workspace" in data:
        axes, step, speed = _workspace(robot, data["workspace"], where)
        _check_size(math.prod(len(values) for values in axes), grid, where)
        segments = _workspace_segments(axes, step, speed)
        cycle = WorkCycle("workspace", segments[:1], held)
    else:
        segments, cycle = _task_segments(robot, data["task"], folder, where)
        _check_size(len(segments), grid, where)
        cycle = WorkCycle(cycle.name, cycle.segments, held or cycle.held)
    held = held_actuators(robot, cycle)
    held_indices(robot, held)  # names checked before any work
    chunk = data.get("chunk", 8)
    if isinstance(chunk, bool) or not isinstance(chunk, int) or not 1 <= chunk <= MAX_CHUNK:
        raise InvalidInputError(
            f"{where}: chunk = {chunk!r} must be a whole number within [1, {MAX_CHUNK:,}]"
        )
    return MapFamily(
        text(data, "name", where, "the map's name", path.stem),
        robot_name,
        hydraulics,
        objectives,
        held,
        segments,
        grid,
        attachment,
        bore,
        chunk,
        flags["bound"],
        flags["energy"],
        flags["circuit"],
    )


def _grid(robot: Robot, table: object, where: str):
    """The design grid: ((parameter, values), ...), the attachment moved, the bore's cylinder."""
    if not isinstance(table, dict):
        raise InvalidInputError(f"{where} must be a table")
    refuse_unknown(table, PARAMETERS, where, "parameters")
    grid, attachment, bore = [], None, None
    for key in PARAMETERS:
        if key not in table:
            continue
        value = table[key]
        if key == "payload":
            values = _values(value, f"{where} payload", "kg", 0.0, MAX_PAYLOAD)
        elif key == "speed":
            values = _values(value, f"{where} speed", "m/s", 1e-6, MAX_SPEED)
        else:
            if not isinstance(value, dict) or "values" not in value:
                raise InvalidInputError(
                    f"{where} {key} must be a table with actuator = ... and values = [...]"
                )
            refuse_unknown(value, DESIGN_KEYS[key], f"{where} {key}")
            actuator = text(value, "actuator", f"{where} {key}", "an actuator's name")
            if actuator not in robot.actuators.names:
                raise InvalidInputError(
                    f"{where} {key}: no actuator {actuator!r}; actuators: "
                    f"{', '.join(robot.actuators.names)}"
                )
            values = _values(value["values"], f"{where} {key} values", "m", -1e3, 1e3)
            if key == "attachment":
                if not isinstance(robot.actuators[actuator], LinearCylinder):
                    raise InvalidInputError(
                        f"{where} attachment: {actuator} is not a LinearCylinder; it has no "
                        "attachment points"
                    )
                end = text(value, "end", f"{where} attachment", "base or rod")
                axis = text(value, "axis", f"{where} attachment", "x, y or z")
                if end not in ENDS or axis not in AXES or len(axis) != 1:
                    raise InvalidInputError(
                        f"{where} attachment: end = {end!r}, axis = {axis!r}; ends: base, rod; "
                        "axes: x, y, z (of the end's link frame)"
                    )
                attachment = (actuator, end, axis)
            else:
                circuit = robot.circuit()
                if actuator not in circuit.names:
                    raise InvalidInputError(
                        f"{where} bore: {actuator} is no cylinder of the circuit; cylinders: "
                        f"{', '.join(circuit.names)}"
                    )
                if not min(values) > circuit.cylinders[circuit.names.index(actuator)].rod:
                    raise InvalidInputError(
                        f"{where} bore values {list(values)} must all exceed the rod of {actuator}"
                    )
                bore = actuator
        grid.append((key, values))
    return tuple(grid), attachment, bore
