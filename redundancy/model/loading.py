"""Loading robots: bundled names, ``robot.toml`` descriptions and URDFs (read and built by
`redundancy.model.urdf`), with their actuators."""

from __future__ import annotations

import importlib.metadata
import importlib.resources
import itertools
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from redundancy.errors import InvalidInputError, RobotDescriptionError, SingularConfigurationError
from redundancy.model.actuators import ActuatorMap, ActuatorSet, attach_frame
from redundancy.model.hydraulics import Circuit, circuit_from_table, read_hydraulics_file
from redundancy.model.robot import AXES, Robot, frame_id
from redundancy.model.schema import Description, Overrides, excerpt, read_toml, toml, validate
from redundancy.model.transmissions import read_actuator_tables, read_cylinders, read_transmissions
from redundancy.model.urdf import Urdf, build_model, read_urdf


def bundled_root() -> Path:
    """Folder holding the bundled robots (``redundancy/robots/`` in the source tree)."""
    return Path(str(importlib.resources.files("redundancy.robots")))


def bundled_robots() -> list[str]:
    """Names of the bundled robots: the folders of `bundled_root` with a ``robot.toml``."""
    return sorted(p.parent.name for p in bundled_root().glob("*/robot.toml"))


URDF_SUFFIXES = (".urdf", ".xacro")


def _describe(robot: str | Path) -> tuple[str, Path, Description, str]:
    """Name, folder, description and its source, of a bundled name or a ``robot.toml``, URDF or
    xacro path (paths it names are relative to the folder the file, not a link to it, is in)."""
    if not isinstance(robot, str | Path):
        raise InvalidInputError(f"robot must be a name or a path; got {robot!r}")
    path = Path(robot)
    if path.is_dir() and (path / "robot.toml").is_file():  # a robot's folder
        if str(robot) in bundled_robots() and not isinstance(robot, Path):
            warnings.warn(
                f"robot {str(robot)!r} is the folder {path.resolve()} (its robot.toml), not the "
                "bundled robot of that name",
                stacklevel=3,
            )
        path = path / "robot.toml"
    urdf = path.suffix.lower() in URDF_SUFFIXES
    if urdf or path.suffix.lower() == ".toml":
        if not path.is_file():
            raise RobotDescriptionError(
                f"no {'URDF file' if urdf else 'robot description'} at {path}"
            )
        folder = path.resolve().parent
    elif str(robot) in bundled_robots():
        folder = bundled_root() / str(robot)
        path = folder / "robot.toml"
    elif path.is_dir():
        raise RobotDescriptionError(
            f"robot {str(robot)!r} is a folder without a robot.toml; give a robot's folder, the "
            f"path of a .urdf, .xacro or robot.toml file, or a bundled robot: "
            f"{', '.join(bundled_robots())}"
        )
    else:
        raise RobotDescriptionError(
            f"unknown robot {str(robot)!r}; bundled robots: {', '.join(bundled_robots())}; "
            "or give the path of a .urdf, .xacro or robot.toml file, or of a folder holding a "
            "robot.toml"
        )
    if urdf:  # named after the file, without its suffixes
        name = re.sub(r"(\.urdf|\.xacro)+$", "", path.name, flags=re.IGNORECASE) or path.name
        return name, folder, Description(urdf=path.name, tool_frame=None, task_axes=AXES), str(path)
    table = read_toml(path, "robot description")
    description = validate(Description, table, str(path), error=RobotDescriptionError)
    return folder.name, folder, description, str(path)


def _urdf_path(folder: Path, reference: str) -> Path:
    """A URDF named relative to the robot's folder, or ``package://<distribution>/<path>`` for
    one shipped by an installed Python distribution (e.g. example-robot-data)."""
    if not reference.startswith("package://"):
        return folder / reference
    distribution, _, inner = reference[len("package://") :].partition("/")
    try:
        files = importlib.metadata.distribution(distribution).files or []
    except importlib.metadata.PackageNotFoundError as error:
        raise RobotDescriptionError(
            f"{reference}: the package {distribution!r} is not installed; "
            f"pip install {distribution}"
        ) from error
    for file in files:
        if str(file).endswith(f"{distribution}/{inner}"):
            return Path(str(file.locate()))
    raise RobotDescriptionError(f"{reference}: no such file in the package {distribution!r}")


def _lock(
    model: pin.Model,
    locked: dict[str, float | None],
    where: str,
    source: str,
    continuous: list[str],
) -> pin.Model:
    """``model`` (of the URDF ``source``) with the ``locked`` joints (from ``where``) fixed at
    their values (neutral where None): within the joint's range, any angle for a
    ``continuous`` one."""
    joints = list(model.names)[1:]
    unknown = [j for j in locked if j not in joints]
    if unknown:
        raise RobotDescriptionError(
            f"{where}: locked joints {unknown} are not joints of {source}; joints: {joints}"
        )
    q = pin.neutral(model)
    for name, value in ((n, v) for n, v in locked.items() if v is not None):
        joint = model.joints[model.getJointId(name)]
        lower, upper = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
        if name in continuous:
            lower, upper = -np.inf, np.inf
        if joint.nq != 1 or not lower <= value <= upper:
            raise RobotDescriptionError(
                f"{where}: locked_joints {name} = {value:g} must be within the joint's range "
                f"[{lower:g}, {upper:g}] (rad or m), on a joint of one coordinate"
            )
        q[joint.idx_q] = value
    if not locked:
        return model
    return pin.buildReducedModel(model, [model.getJointId(j) for j in locked], q)


def _tool(model: pin.Model, description: Description, where: str) -> str:
    """The tool frame: ``tool_frame``, a link (by default the one the most joints move, of
    several the last), or ``tool``, a point on a link added to ``model`` as a frame named
    `TOOL_POINT` (numbered where the URDF has a frame of that name)."""
    tool = description.tool
    if tool is not None:

        def refused(links: str) -> str:
            link = excerpt(tool.link, toml)
            return f"{where} tool.link = {link} is not a link of the URDF; links: {links}"

        names = itertools.chain([TOOL_POINT], (f"{TOOL_POINT} {i}" for i in itertools.count(2)))
        name = next(n for n in names if not model.existFrame(n))
        attach_frame(model, name, tool.link, np.array(tool.xyz), refused)
        return name
    bodies = [f for f in model.frames if f.type == pin.FrameType.BODY]
    if description.tool_frame is None:  # the deepest link: most joints between it and the root
        return max(reversed(bodies), key=lambda f: len(model.supports[f.parentJoint])).name
    if description.tool_frame not in (f.name for f in bodies):
        raise RobotDescriptionError(
            f"{where}: tool frame {description.tool_frame!r} is not a link of the URDF; links: "
            f"{[f.name for f in bodies]}"
        )
    return description.tool_frame


TOOL_POINT = "tool point"  # the frame of a tool given as a point on a link


def _actuators(
    root: etree._Element, description: Description, source: str, where: str, locked: dict
) -> tuple[list, list[str]]:
    """The declared actuators, from the URDF's transmissions and robot.toml's tables, less
    those on locked joints, and the names of those (dropped with a warning, their cylinders
    with them)."""
    declared = read_transmissions(root, source)
    declared += read_actuator_tables(description.actuators, where)
    dropped = [a.name for a in declared if a.joint in locked]
    if dropped:
        warnings.warn(f"actuators on locked joints are dropped: {', '.join(dropped)}", stacklevel=3)
    return [a for a in declared if a.joint not in locked], dropped


STEP = np.radians(0.25)  # rad: the grid a continuous joint's stroke range is first sought on
BISECTIONS = 40  # halvings of a grid step that locate each end of the range (to 1e-14 rad)


def _along(robot: Robot, column: int, values: np.ndarray) -> np.ndarray:
    """Configurations (k, n) with joint ``column`` at ``values`` (k,) and the other joints at
    rest (0, or the end of their range nearest it)."""
    q = np.repeat(np.clip(0.0, robot.lower, robot.upper)[None], len(values), axis=0)
    q[:, column] = values
    return q


def _stroke_arc(robot: Robot, column: int, actuator: ActuatorMap) -> tuple[float, float] | None:
    """The angles of joint ``column`` (rad) over which ``actuator`` stays inside its stroke, the
    other joints at rest: found on a grid over ±2 turns, each end then bisected; of several arcs,
    the one nearest 0. None where the stroke admits no angle, or every one."""

    def inside(theta: np.ndarray) -> np.ndarray:
        x = actuator.evaluate(robot.kinematics(_along(robot, column, theta)))[0]
        return (x >= actuator.lower) & (x <= actuator.upper)

    angles = np.arange(-2 * np.pi, 2 * np.pi + STEP / 2, STEP)
    kept = inside(angles)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], kept.astype(int), [0]])))
    arcs = [(a, b - 1) for a, b in zip(edges[::2], edges[1::2])]
    if not arcs or kept.all():
        return None
    first, last = min(arcs, key=lambda arc: max(angles[arc[0]], -angles[arc[1]], 0.0))
    ends = []
    for end, outward in ((first, -1), (last, 1)):
        good, bad = angles[end], angles[end] + outward * STEP
        for _ in range(BISECTIONS):
            middle = (good + bad) / 2
            good, bad = (middle, bad) if inside(np.array([middle]))[0] else (good, middle)
        ends.append(float(good))
    return ends[0], ends[1]


ARM = 1e-2  # |∂x_i/∂q_i| (m/rad, or m/m) below which an actuator cannot move its joint
SAMPLES = 33  # values of a joint over its range at which `_check_arms` reads the arm


def _check_arms(robot: Robot) -> None:
    """Every actuator moves its joint: somewhere over the joint's range (±π or ±1 m where it
    is unbounded), the other joints at rest, |∂x_i/∂q_i| reaches `ARM`; else (an attachment
    point on its joint's axis: A singular everywhere) one line names it and its table."""
    for actuator in robot.actuators:
        column = actuator.index
        span = np.pi if robot.rotary_joints[column] else 1.0
        lower, upper = np.clip([robot.lower[column], robot.upper[column]], -span, span)
        q = _along(robot, column, np.linspace(lower, upper, SAMPLES))
        try:
            arm = np.abs(actuator.evaluate(robot.kinematics(q))[1][:, column]).max()
        except SingularConfigurationError:  # a linkage that cannot close there: said in use
            continue
        if arm >= ARM:
            continue
        per = "rad" if robot.rotary_joints[column] else "m"
        links = _apart(robot, actuator)
        why = (
            f"its points lie on {', '.join(map(repr, links))}, which {actuator.joint} does not "
            "move one against the other; attach them on links either side of the joint"
            if links
            else "an attachment point lies on or near the joint's axis; attach each at least "
            f"{ARM * 1000:g} mm off it"
        )
        raise RobotDescriptionError(
            f"{actuator.declared_in}: {actuator.name} cannot move {actuator.joint}: |∂x/∂q| is "
            f"at most {arm:.3g} {actuator.unit}/{per} over the joint's range, below {ARM:g} (A is "
            f"singular): {why}"
        )


def _apart(robot: Robot, actuator) -> list[str]:
    """The links ``actuator``'s points lie on, where its joint moves all of them or none (each
    from the root to the link's joint, a mimic joint counting for the joint it follows): then
    no point moves against another; else none."""
    model = robot.model
    joint = model.getJointId(actuator.joint)
    followers = {m for m, led in zip(model.mimicking_joints, model.mimicked_joints) if led == joint}
    frames = [model.frames[f] for f in actuator.frames]
    moved = {bool({joint, *followers} & set(model.supports[f.parentJoint])) for f in frames}
    if len(frames) < 2 or len(moved) != 1:
        return []
    return list(dict.fromkeys(model.frames[f.parentFrame].name for f in frames))


def _bound_by_strokes(robot: Robot, continuous: list[str]) -> None:
    """Give each ``continuous`` joint whose actuator has a finite stroke the arc over which the
    actuator stays inside it (`_stroke_arc`); where there is none, it stays unbounded."""
    for joint in continuous:
        column = robot.joint_names.index(joint)
        actuator = next(a for a in robot.actuators if a.index == column)
        if np.isfinite([actuator.lower, actuator.upper]).any():
            arc = _stroke_arc(robot, column, actuator)
            if arc is not None:
                robot.model.lowerPositionLimit[column], robot.model.upperPositionLimit[column] = arc


def load_robot(
    robot: str | Path,
    payload: float | None = None,
    task_axes: str | None = None,
    hydraulics: str | Path | None = None,
) -> Robot:
    """Load a bundled robot by name, or a robot from a ``robot.toml``, ``.urdf`` or ``.xacro``
    path, or a folder holding a ``robot.toml`` (its schema: docs/machines.md). A bare URDF or
    xacro takes the link the most joints move as the tool (of several, the last) and
    "xyz" as the task axes. ``payload`` (kg, ≥ 0) is a point mass at the tool frame (None: the
    description's, or 0); ``task_axes`` overrides the description's. The
    circuit is the ``[hydraulics]`` table of the TOML file ``hydraulics`` if given, else the
    description's. Meshes no file answers and links without inertia (a kinematic-only robot:
    anything needing masses refuses) are each named in one warning; an ``<inertial>`` that is
    there must hold numbers a body can have.
    """
    name, folder, description, where = _describe(robot)
    urdf_path = _urdf_path(folder, description.urdf)
    if not urdf_path.is_file():
        raise RobotDescriptionError(
            f"{where}: urdf = {excerpt(description.urdf, toml)}: no such file {urdf_path}"
        )
    urdf = read_urdf(urdf_path)
    if urdf.missing_meshes:
        warnings.warn(
            f"{urdf.source}: meshes not found, the playback draws those links as hulls: "
            f"{', '.join(urdf.missing_meshes)}",
            stacklevel=2,
        )
    locked = description.locked_joints
    locked = dict(locked) if isinstance(locked, dict) else dict.fromkeys(locked)
    model, continuous = build_model(urdf, locked)
    model = _lock(model, locked, where, urdf.source, continuous)
    for joint in set(continuous) - set(locked):  # unbounded, unless a stroke bounds it (below)
        index = model.joints[model.getJointId(joint)].idx_q
        model.lowerPositionLimit[index], model.upperPositionLimit[index] = -np.inf, np.inf
    tool_frame = _tool(model, description, where)
    given = validate(Overrides, {"payload": payload, "task_axes": task_axes}, "load_robot")
    payload = description.payload if given.payload is None else given.payload
    if payload > 0:  # a point mass at the tool frame, carried by the tool's joint
        tool = model.frames[frame_id(model, tool_frame)]
        point_mass = pin.Inertia(payload, tool.placement.translation, np.zeros((3, 3)))
        model.inertias[tool.parentJoint] = model.inertias[tool.parentJoint] + point_mass
    kept, dropped = _actuators(urdf.root, description, urdf.source, where, locked)
    actuators = ActuatorSet.bind(kept, model)
    actuators.source = where
    loaded = Robot(
        name,
        model,
        tool_frame,
        given.task_axes or description.task_axes,
        actuators,
        payload,
        urdf_path,
        None if description.task is None else folder / description.task,
        _circuit(urdf, actuators, dropped, description, where, hydraulics),
        urdf.text,
        urdf.missing_meshes,
        urdf.zero_masses,
    )
    _check_arms(loaded)
    _bound_by_strokes(loaded, [j for j in continuous if j not in locked])
    if loaded.kinematic_only:
        warnings.warn(
            f"{loaded.massless}; the robot is kinematic only (the velocity objective, playback "
            "and check work; anything needing masses refuses)",
            stacklevel=2,
        )
    return loaded


def _circuit(
    urdf: Urdf,
    actuators: ActuatorSet,
    dropped: list[str],
    description: Description,
    where: str,
    hydraulics: str | Path | None,
) -> Circuit | None:
    """The machine's circuit: the ``[hydraulics]`` table of the file ``hydraulics`` if given,
    else the description's (``where``), with the cylinders the URDF's transmissions declare;
    None (with a warning where the URDF declares cylinders) without a table."""
    declared = read_cylinders(urdf.root, urdf.source)
    if hydraulics is not None:
        if not isinstance(hydraulics, str | os.PathLike):
            raise InvalidInputError(
                f"hydraulics must be the path of a TOML file with a [hydraulics] table; got "
                f"{type(hydraulics).__name__} {hydraulics!r}"[:240]
            )
        table, origin = read_hydraulics_file(Path(hydraulics)), str(hydraulics)
    elif description.hydraulics is not None:
        table, origin = description.hydraulics, where
    else:
        if declared:
            warnings.warn(
                f"{urdf.source} declares cylinders {sorted(declared)} but no [hydraulics] "
                "table gives the machine's supply; hydraulics are off",
                stacklevel=3,
            )
        return None
    rotary = actuators.rotary.tolist()
    return circuit_from_table(
        table, origin, actuators.names, rotary, declared, urdf.source, dropped
    )
