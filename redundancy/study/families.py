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
import warnings
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
import pinocchio as pin
from pydantic import AfterValidator, Field, model_validator
from pydantic_core import PydanticCustomError

from redundancy.errors import InvalidInputError, prefixed
from redundancy.model.actuators import ActuatorSet, LinearCylinder
from redundancy.model.loading import bundled_robots, load_robot
from redundancy.model.robot import AXES, Robot
from redundancy.model.schema import (
    DECLARED,
    MAX_OFFSET,
    MM_PER_S,
    Names,
    Table,
    either,
    excerpt,
    quantity,
    read_toml,
    toml,
    validate,
)
from redundancy.model.values import MAX_PAYLOAD, MAX_SPEED, is_real, is_whole
from redundancy.planning.starts import held_actuators
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.objectives import OBJECTIVES
from redundancy.study.check import held_problems

PARAMETERS = ("payload", "speed", "attachment", "bore")  # the design grid's keys, in order
MAX_PROBLEMS = 2_000_000  # problems of one family: its table, held in memory at about 200 bytes
# per row and objective, stays under 1 GB with two objectives; split a larger family
MAX_CHUNK = 10_000
MAX_COUNT = 100_000  # values of one range
WORKSPACE_SAMPLES = 4096  # joint-space samples spanning the reachable workspace's extent


class Range(Table):
    """A design parameter's values as a range: ``{from = a, to = b, count = k}``."""

    start: float = Field(alias="from")
    to: float
    count: int = Field(ge=1, le=MAX_COUNT, description="values from a to b")


def design_values(lower: float, upper: float, hint: str = "") -> Any:
    """A design parameter's values, a list of numbers or a `Range`, each within [lower,
    upper] (``hint``: the likely unit mistake beyond), read as a tuple of floats."""

    def expand(given: Range | list[float]) -> tuple[float, ...]:
        found = (
            given if isinstance(given, list) else np.linspace(given.start, given.to, given.count)
        )
        if not len(found):
            raise PydanticCustomError(
                DECLARED, "gives no values; give a list of numbers or {from = a, to = b, count = k}"
            )
        if not all(lower <= v <= upper for v in found):
            raise PydanticCustomError(
                DECLARED, f"must be within [{lower:g}, {upper:g}]" + (f"; {hint}" if hint else "")
            )
        return tuple(float(v) for v in found)

    return Annotated[either(Range, list[float]), AfterValidator(expand)]


MM = "did you give mm? 1 m = 1000 mm"
Offsets = design_values(-MAX_OFFSET, MAX_OFFSET, MM)  # m, of a point in its link's frame
Bores = design_values(0.005, 1.0, MM)  # m: the 5-1000 mm of a hydraulics file's bores
Payloads = design_values(0.0, MAX_PAYLOAD)  # kg
Speeds = design_values(1e-6, MAX_SPEED, MM_PER_S)  # m/s


class Workspace(Table):
    """The ``[workspace]`` table: segments of one length and direction from a grid of starts."""

    length: float = quantity("each segment's length", "m", 1e-6, 1e3)
    direction: list[float] = Field(description="along the task axes; normalised")
    speed: float = quantity("along each segment", "m/s", 1e-6, MAX_SPEED, 0.5, above=MM_PER_S)
    grid: dict[str, Any] = Field(description="per task axis: [from, to, count], or a count")


class TaskTable(Table):
    """The ``[task]`` table: segments of a task file."""

    file: str | None = Field(None, description="the task file, relative to the map file")
    segments: Names | None = Field(
        None, min_length=1, description="segments of the task file (default: every one)"
    )


class Attachment(Table):
    """An attachment coordinate the grid moves: ``{actuator, end, axis, values}``."""

    actuator: str = Field(description="an actuator's name")
    end: Literal["base", "rod"] | None = None
    axis: Literal["x", "y", "z"] | None = Field(None, description="of the end's link frame")
    values: Offsets = Field(description="m, in the end's link frame")  # type: ignore[valid-type]


class Bore(Table):
    """A cylinder's bore the grid varies: ``{actuator, values}``."""

    actuator: str = Field(description="an actuator's name")
    values: Bores = Field(description="m")  # type: ignore[valid-type]


class Grid(Table):
    """The design grid: each parameter's values."""

    entries: ClassVar[str] = "parameters"
    payload: Payloads | None = Field(None, description="kg")  # type: ignore[valid-type]
    speed: Speeds | None = Field(None, description="m/s")  # type: ignore[valid-type]
    attachment: Attachment | None = None
    bore: Bore | None = None


class Family(Table):
    """A map file (see the module docstring)."""

    name: str | None = Field(None, min_length=1, description="the family's name")
    robot: str = Field("hiab031", description="bundled name or robot path")
    hydraulics: str | None = Field(None, description="a [hydraulics] file")
    objectives: Names = Field(
        ["velocity", "energy"], description=f"objectives: {', '.join(OBJECTIVES)}"
    )
    held: Names = Field([], description="actuators the search holds")
    chunk: int = Field(8, ge=1, le=MAX_CHUNK, description="problems per chunk of work")
    bound: bool = False
    energy: bool = False
    circuit: bool = False
    workspace: Workspace | None = None
    task: TaskTable | None = None
    grid: Grid = Grid()

    @model_validator(mode="before")
    @classmethod
    def _one_source(cls, data: Any) -> Any:
        if isinstance(data, dict) and ("workspace" in data) == ("task" in data):
            raise PydanticCustomError(
                DECLARED, "give the segments by one table, [workspace] or [task]"
            )
        return data


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

    @cached_property
    def held_unit(self) -> str:
        """The SI unit of the held actuators' values: m, or rad where they turn."""
        actuators = self.robot_for(Design()).actuators
        return " or ".join(sorted({actuators[name].unit for name in self.held}))

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
        return dataclasses.replace(segment, speed=design.speed)  # its path and profile kept


def _digest(digest, value: object) -> None:
    """Feed ``value`` to ``digest``: a dataclass field by field, those its equality compares
    (what its fields are, not what it has cached, nor where it was read from), an array by its
    type, shape and bytes (whole: its repr would elide a long polyline's middle, and cost
    seconds on a large family), a sequence item by item, anything else by its repr."""
    if dataclasses.is_dataclass(value):
        digest.update(type(value).__name__.encode())
        for field in dataclasses.fields(value):
            if field.compare:
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
    frame) and one cylinder's bore set to ``bore`` (m). Its loading notes (a joint driven
    directly, an actuator dropped) are not said again: `read_family` said them, where it loaded
    the robot, and a map's workers, each loading its variants, printed them raw."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
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
            cylinder.name, cylinder.joint, cylinder.lower, cylinder.upper, **ends
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


def _axis_values(value: object, where: str, extent: tuple[float, float]) -> tuple[float, ...]:
    """[from, to, count], or a count over ``extent``, as the grid's coordinates."""
    if is_whole(value):
        value = [extent[0], extent[1], value]
    if not (
        isinstance(value, list)
        and len(value) == 3
        and all(is_real(v) and math.isfinite(v) for v in value[:2])
    ):
        raise InvalidInputError(
            f"{where} = {excerpt(value, toml)} must be [from, to, count] (m) or a count alone"
        )
    if not is_whole(value[2], 1, MAX_COUNT):
        raise InvalidInputError(
            f"{where}: count {excerpt(value[2], toml)} must be a whole number ≥ 1"
        )
    return tuple(float(v) for v in np.linspace(*value))


def workspace_extent(robot: Robot) -> np.ndarray:
    """Per task axis, the smallest and largest tool coordinate over `WORKSPACE_SAMPLES` scrambled
    Halton configurations inside the joint limits, (m, 2) in m."""
    from scipy.stats import qmc

    unit = qmc.Halton(d=robot.n, scramble=True, seed=11).random(WORKSPACE_SAMPLES)
    y = robot.task_point(robot.kinematics(robot.lower + (robot.upper - robot.lower) * unit))[0]
    return np.stack([y.min(axis=0), y.max(axis=0)], axis=1)


def _workspace(
    robot: Robot, table: Workspace, where: str
) -> tuple[list[tuple[float, ...]], np.ndarray, float]:
    """The ``[workspace]`` table: the grid's coordinates per task axis, the step from a
    segment's start to its end (m) and the speed along it (m/s)."""
    direction = np.array(table.direction)
    if direction.shape != (robot.m,):
        raise InvalidInputError(
            f"{where}: direction = {excerpt(table.direction)} has {direction.size} coordinates; "
            f"the robot's task has {robot.m}"
        )
    if not np.linalg.norm(direction) > 0:
        raise InvalidInputError(f"{where}: direction = {direction.tolist()} must be nonzero")
    unknown = sorted(set(table.grid) - set(robot.task_axes))
    if unknown:
        raise InvalidInputError(
            f"{where}: [workspace.grid] has {unknown}; task axes: {', '.join(robot.task_axes)}"
        )
    extent = workspace_extent(robot)
    axes = []
    for a, axis in enumerate(robot.task_axes):
        if axis not in table.grid:
            raise InvalidInputError(f"{where}: [workspace.grid] misses the task axis {axis!r}")
        axes.append(
            _axis_values(table.grid[axis], f"{where}: workspace.grid.{axis}", tuple(extent[a]))
        )
    return axes, table.length * direction / np.linalg.norm(direction), table.speed


def _check_size(segments: int, grid: tuple[tuple[str, tuple], ...], where: str) -> None:
    """Refuse a family of more than `MAX_PROBLEMS` problems, counted from its ``segments``
    and the design ``grid``'s sizes before any of them is built."""
    problems = segments * math.prod(len(values) for _, values in grid)
    if problems > MAX_PROBLEMS:
        raise InvalidInputError(
            f"{where}: the family has {problems:,} problems; it must have at most "
            f"{MAX_PROBLEMS:,} (split a larger family)"
        )


def _task_segments(robot: Robot, table: TaskTable, folder: Path, where: str):
    if table.file is not None:
        path = folder / table.file
    elif robot.task_file is not None:
        path = robot.task_file
    else:
        raise InvalidInputError(f"{where}: [task] needs file = ...; {robot.name} has no task")
    cycle = WorkCycle.from_toml(path, dimension=robot.m)
    with prefixed(f"{where}: [task] segments"):
        chosen = table.segments
        segments = cycle.segments if chosen is None else tuple(cycle[s] for s in chosen)
    return segments, cycle


def read_family(path: Path | str) -> MapFamily:
    """The family declared in the map file ``path`` (see the module docstring)."""
    path = Path(path)
    table = read_toml(path, "map file")  # one line where it cannot be read (a loop of links)
    where, folder = str(path), path.resolve().parent
    family = validate(Family, table, where)
    robot_name = family.robot
    if not (robot_name in bundled_robots() and not (folder / robot_name).exists()):
        robot_name = str(folder / robot_name)
    hydraulics = None if family.hydraulics is None else str(folder / family.hydraulics)
    robot = load_robot(robot_name, hydraulics=hydraulics)
    for name in family.objectives:
        if name not in OBJECTIVES:
            raise InvalidInputError(
                f"{where}: objective {name!r} unknown; objectives: {', '.join(OBJECTIVES)}"
            )
    if not family.objectives:
        raise InvalidInputError(f"{where}: objectives = [] names none; give at least one")
    if family.energy or family.circuit:
        robot.circuit()  # says how to declare one
    held = tuple(family.held)
    grid, attachment, bore = _grid(robot, family.grid, f"{where}: [grid]")
    if family.workspace is not None:
        axes, step, speed = _workspace(robot, family.workspace, f"{where}: [workspace]")
        _check_size(math.prod(len(values) for values in axes), grid, where)
        segments = tuple(  # from every point of the grid to that point + step
            Segment(f"start {i}", np.array(start), np.array(start) + step, speed)
            for i, start in enumerate(itertools.product(*axes))
        )
        cycle = WorkCycle("workspace", segments[:1], held, source=where)
    else:
        segments, cycle = _task_segments(robot, family.task, folder, where)  # type: ignore[arg-type]
        _check_size(len(segments), grid, where)
        source = where if family.held else cycle.source  # the file that names them
        cycle = WorkCycle(cycle.name, cycle.segments, held or cycle.held, source=source)
    held = held_actuators(robot, cycle)
    problems = held_problems(robot, cycle)  # names, count, strokes, directions: before any work
    if problems:
        raise InvalidInputError(problems[0])
    return MapFamily(
        path.stem if family.name is None else family.name,
        robot_name,
        hydraulics,
        tuple(family.objectives),
        held,
        segments,
        grid,
        attachment,
        bore,
        family.chunk,
        family.bound,
        family.energy,
        family.circuit,
    )


def _grid(robot: Robot, table: Grid, where: str):
    """The design grid: ((parameter, values), ...), the attachment moved, the bore's cylinder."""
    grid, attachment, bore = [], None, None
    for key in PARAMETERS:
        value = getattr(table, key)
        if value is None:
            continue
        if isinstance(value, Attachment | Bore):
            if value.actuator not in robot.actuators.names:
                raise InvalidInputError(
                    f"{where} {key}: no actuator {value.actuator!r}; actuators: "
                    f"{', '.join(robot.actuators.names)}"
                )
            if isinstance(value, Attachment):
                if not isinstance(robot.actuators[value.actuator], LinearCylinder):
                    raise InvalidInputError(
                        f"{where} attachment: {value.actuator} is not a LinearCylinder; it has no "
                        "attachment points"
                    )
                if value.end is None or value.axis is None:
                    raise InvalidInputError(
                        f"{where} attachment: end = {value.end!r}, axis = {value.axis!r}; ends: "
                        "base, rod; axes: x, y, z (of the end's link frame)"
                    )
                attachment = (value.actuator, value.end, value.axis)
            else:
                circuit = robot.circuit()
                if value.actuator not in circuit.names:
                    raise InvalidInputError(
                        f"{where} bore: {value.actuator} is no cylinder of the circuit; "
                        f"cylinders: {', '.join(circuit.names)}"
                    )
                rod = circuit.cylinders[circuit.names.index(value.actuator)].rod
                if not min(value.values) > rod:
                    raise InvalidInputError(
                        f"{where} bore values {list(value.values)} must all exceed the rod of "
                        f"{value.actuator}"
                    )
                bore = value.actuator
            value = value.values
        grid.append((key, value))
    return tuple(grid), attachment, bore
