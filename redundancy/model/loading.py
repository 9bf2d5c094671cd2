"""Loading robots: bundled names, ``robot.toml`` descriptions and URDFs, with their actuators.

This is the only module that builds Pinocchio models (`load_robot`).
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import importlib.resources
import math
import os
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from redundancy.errors import InvalidInputError, RobotDescriptionError
from redundancy.model.actuators import ActuatorSet, driven_joints
from redundancy.model.hydraulics import circuit_from_table, read_hydraulics_file
from redundancy.model.parameters import number_or_text
from redundancy.model.robot import AXES, Robot, frame_id
from redundancy.model.schema import Description, Payload, read_toml, validate
from redundancy.model.transmissions import (
    read_actuator_tables,
    read_cylinders,
    read_transmissions,
)


def bundled_root() -> Path:
    """Folder holding the bundled robots (``robots/`` in the source tree)."""
    return Path(str(importlib.resources.files("redundancy.robots")))


def bundled_robots() -> list[str]:
    """Names of the bundled robots: the folders of `bundled_root` with a ``robot.toml``."""
    return sorted(p.parent.name for p in bundled_root().glob("*/robot.toml"))


def _read_description(path: Path) -> Description:
    """The robot description ``path`` (a ``robot.toml``), checked."""
    return validate(
        Description, read_toml(path, "robot description"), str(path), error=RobotDescriptionError
    )


URDF_SUFFIXES = (".urdf", ".xacro")


def _file_name(path: Path) -> str:
    """A robot's name from its URDF or xacro file: the file's name without those suffixes."""
    name = path.name
    while Path(name).suffix in URDF_SUFFIXES:
        name = Path(name).stem
    return name or path.name


def _describe(robot: str | Path) -> tuple[str, Path, Description, str]:
    """Name, folder, description (robot.toml contents) and where the description came from, of
    a bundled name or a file path. A robot loaded from a path is named after its folder (a
    ``robot.toml``) or its file (a URDF or xacro). Paths a file names are relative to the folder
    the file itself is in: reached through a symbolic link, the folder the link points into."""
    if not isinstance(robot, str | Path):
        raise InvalidInputError(f"robot must be a name or a path; got {robot!r}")
    path = Path(robot)
    if path.suffix in URDF_SUFFIXES:
        if not path.is_file():
            raise RobotDescriptionError(f"no URDF file at {path}")
        bare = Description(urdf=path.name, tool_frame=None, task_axes=AXES)
        return _file_name(path), path.resolve().parent, bare, str(path)
    if path.suffix == ".toml":
        if not path.is_file():
            raise RobotDescriptionError(f"no robot description at {path}")
        folder = path.resolve().parent
        return folder.name, folder, _read_description(path), str(path)
    names = bundled_robots()
    if str(robot) not in names:
        raise RobotDescriptionError(
            f"unknown robot {str(robot)!r}; bundled robots: {', '.join(names)}; "
            "or give the path of a .urdf, .xacro or robot.toml file"
        )
    folder = bundled_root() / str(robot)
    source = folder / "robot.toml"
    return str(robot), folder, _read_description(source), str(source)


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


def _urdf_text(path: Path) -> bytes:
    """The URDF document of ``path`` (its encoding is the XML's to declare); a ``.xacro`` file
    is expanded by the xacro package."""
    if path.suffix != ".xacro":
        try:
            return path.read_bytes()
        except OSError as error:
            raise RobotDescriptionError(f"{path}: not readable: {error.strerror}") from None
    import xacro

    try:
        with contextlib.redirect_stdout(sys.stderr), _captured_stderr():
            document = xacro.process_file(str(path))
    except Exception as error:  # xacro raises its own and its parsers' errors
        reason = str(error).strip().splitlines()[0] if str(error).strip() else ""
        raise RobotDescriptionError(
            f"{path}: xacro cannot expand it: {type(error).__name__}: {reason}"
        ) from error
    return document.toxml().encode()


FREE = ("floating", "planar")  # URDF joint types of a base that moves freely


def _intake(
    document: bytes, source: str, locked: dict[str, float | None]
) -> tuple[etree._Element, list[str]]:
    """The URDF's XML root, made ready for Pinocchio, and the continuous joints.

    A continuous joint becomes a revolute one (one coordinate, the angle in rad, instead of
    Pinocchio's (cos, sin) pair); its range is made unbounded once the model is built. A
    floating or planar joint is refused unless it is locked, with the fix in the message. A
    mimic joint following a locked joint is locked too, at multiplier · value + offset (added
    to ``locked``)."""
    try:
        root = etree.fromstring(document)
    except etree.XMLSyntaxError as error:
        raise RobotDescriptionError(f"{source}: not readable XML: {error}") from None
    continuous = []
    for joint in root.findall("joint"):
        kind, name = joint.get("type"), joint.get("name")
        if kind in FREE and name not in locked:
            raise RobotDescriptionError(
                f"{source}: joint {name!r} is {kind}, a base that moves freely; the toolkit "
                f'models machines on a fixed base: add locked_joints = ["{name}"] to '
                f'robot.toml (the base stays at the joint\'s origin) or make it type="fixed"'
            )
        mimic = joint.find("mimic")
        if mimic is not None and mimic.get("joint") in locked and name not in locked:
            texts = (mimic.get("multiplier", "1"), mimic.get("offset", "0"))
            try:
                multiplier, offset = (float(t) for t in texts)
            except ValueError:
                raise RobotDescriptionError(
                    f"{source}: joint {name!r}: <mimic multiplier={texts[0]!r} "
                    f"offset={texts[1]!r}> must be numbers"
                ) from None
            joint.remove(mimic)
            locked[name] = multiplier * (locked[mimic.get("joint")] or 0.0) + offset
        if kind == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = etree.SubElement(joint, "limit", effort="0", velocity="0")
            limit.set("lower", repr(-math.pi))
            limit.set("upper", repr(math.pi))
            continuous.append(name)
    return root, continuous


INERTIA = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")  # <inertia>'s attributes, kg·m²
INERTIA_TOLERANCE = 1e-6  # of the largest principal moment: what a file's rounding may cost


def _inertial_values(
    inertial: etree._Element,
    tag: str,
    attributes: tuple[str, ...],
    where: str,
    meaning: str,
    default: str | None = None,
    lower: float = -math.inf,
) -> np.ndarray:
    """The numbers the ``attributes`` of the ``<inertial>``'s child ``tag`` hold, each finite and
    ≥ ``lower``: one per attribute, or as many as ``default`` holds where it is given (the text
    of an attribute left out, or of every one where the child is); otherwise one line naming
    the link (``where``), the child as written and what it must be (``meaning``)."""
    element = inertial.find(tag)
    if element is None and default is None:
        raise RobotDescriptionError(f"{where}: <inertial> has no <{tag}>; it needs one: {meaning}")
    each = 1 if default is None else len(default.split())
    given = {} if element is None else dict(element.attrib)
    texts = [given.get(a, default) or "" for a in attributes]
    values = [number_or_text(v) for text in texts for v in text.split()]
    if len(values) != each * len(attributes) or not all(
        isinstance(v, float) and math.isfinite(v) and v >= lower for v in values
    ):
        written = etree.tostring(element, encoding="unicode", with_tail=False)
        raise RobotDescriptionError(f"{where} {written} must be {meaning}")
    return np.array(values)


def _check_inertials(root: etree._Element, source: str) -> tuple[str, ...]:
    """Every link's ``<inertial>`` (of the URDF ``source``) holds numbers a body can have: its
    origin finite, its mass finite and ≥ 0, its inertia finite and a body's rotational inertia
    (`_check_inertia`). Where urdfdom cannot read one, Pinocchio drops it without a word,
    leaving the link massless; a negative mass or moment it keeps. Returns the links whose
    ``<inertial>`` gives a mass of 0."""
    zero_masses = []
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        where = f"{source}: link {link.get('name')!r}"
        origin = 'xyz="x y z" rpy="r p y", finite numbers (m, rad)'
        _inertial_values(inertial, "origin", ("xyz", "rpy"), where, origin, "0 0 0")
        mass = "a finite number ≥ 0 (the link's mass, kg)"
        if _inertial_values(inertial, "mass", ("value",), where, mass, lower=0.0)[0] == 0:
            zero_masses.append(link.get("name"))
        inertia = f"six finite numbers {', '.join(INERTIA)} (kg·m², about the centre of mass)"
        _check_inertia(
            inertial, _inertial_values(inertial, "inertia", INERTIA, where, inertia), where
        )
    return tuple(zero_masses)


def _check_inertia(inertial: etree._Element, entries: np.ndarray, where: str) -> None:
    """The ``<inertia>`` of ``inertial`` (its ``entries``, ixx ... izz) is a body's rotational
    inertia: symmetric positive semi-definite, and each principal moment at most the sum of the
    other two, to `INERTIA_TOLERANCE`; otherwise one line naming the link (``where``), the
    element as written and its principal moments. (Six entries make a symmetric matrix; with
    the moments a ≤ b ≤ c, a + b ≥ c gives the other two inequalities and a ≥ c − b ≥ 0.)"""
    ixx, ixy, ixz, iyy, iyz, izz = entries
    moments = np.linalg.eigvalsh([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    if moments[0] + moments[1] >= moments[2] - INERTIA_TOLERANCE * np.abs(moments).max():
        return
    written = etree.tostring(inertial.find("inertia"), encoding="unicode", with_tail=False)
    raise RobotDescriptionError(
        f"{where} {written} is not a body's rotational inertia: its principal moments "
        f"[{', '.join(f'{m:.4g}' for m in moments)}] kg·m² must be ≥ 0 and each at most the "
        "sum of the other two"
    )


def _package_dirs(folder: Path) -> list[Path]:
    """Where a mesh named ``package://<package>/...`` is looked for: ``<package>`` in the
    URDF's folder or one of its ancestors."""
    return [folder.resolve(), *folder.resolve().parents]


def _mesh_path(filename: str, folder: Path) -> Path | None:
    """The file a URDF mesh reference names (``package://``, ``file://``, absolute or relative
    to the URDF's folder), or None where no such file exists."""
    if filename.startswith("package://"):
        inner = filename[len("package://") :]
        candidates = [directory / inner for directory in _package_dirs(folder)]
    else:
        candidates = [folder / filename.removeprefix("file://")]
    return next((c.resolve() for c in candidates if c.is_file()), None)


def _resolve_meshes(root: etree._Element, folder: Path) -> list[str]:
    """Point every visual mesh of the URDF at its file, by absolute path, so that the text
    describes the robot on its own; return the references no file answers."""
    missing = []
    for mesh in root.findall("link/visual/geometry/mesh"):
        filename = mesh.get("filename", "")
        found = _mesh_path(filename, folder)
        if found is None:
            missing.append(filename)
        else:
            mesh.set("filename", str(found))
    return list(dict.fromkeys(missing))


def _build_model(root: etree._Element, source: str) -> pin.Model:
    """The Pinocchio model of the URDF ``root``, mimic joints honoured."""
    text = etree.tostring(root, encoding="unicode")
    failure: Exception | None = None
    with _captured_stderr() as said:
        try:
            model = pin.buildModelFromXML(text, mimic=True)
        except (ValueError, RuntimeError) as error:
            failure = error
    if failure is not None:
        reason = next((line for line in said() if line.strip()), str(failure).splitlines()[0])
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: {reason.strip().removeprefix('Error:').strip()}"
        ) from None
    return model


def _lock(model: pin.Model, locked: dict[str, float | None], where: str, source: str) -> pin.Model:
    """``model`` (of the URDF ``source``) with the ``locked`` joints (from ``where``) fixed at
    their values (neutral where None)."""
    joints = list(model.names)[1:]
    unknown = [j for j in locked if j not in joints]
    if unknown:
        raise RobotDescriptionError(
            f"{where}: locked joints {unknown} are not joints of {source}; joints: {joints}"
        )
    q = pin.neutral(model)
    for name, value in locked.items():
        joint = model.joints[model.getJointId(name)]
        if value is None:
            continue
        lower = model.lowerPositionLimit[joint.idx_q]
        upper = model.upperPositionLimit[joint.idx_q]
        if joint.nq != 1 or not lower <= value <= upper:
            raise RobotDescriptionError(
                f"{where}: locked_joints {name} = {value:g} must be within the joint's range "
                f"[{lower:g}, {upper:g}] (rad or m), on a joint of one coordinate"
            )
        q[joint.idx_q] = value
    if not locked:
        return model
    return pin.buildReducedModel(model, [model.getJointId(j) for j in locked], q)


def _check_joints(model: pin.Model, source: str) -> None:
    odd = [
        f"{name} ({joint.shortname()})"
        for name, joint in zip(model.names[1:], model.joints[1:])
        if joint.nv > 0 and (joint.nq != 1 or joint.nv != 1)
    ]
    if odd:
        raise RobotDescriptionError(
            f"{source}: joints {odd} have more than one coordinate; the toolkit handles "
            "revolute, continuous, prismatic and mimic joints: lock the others with "
            "locked_joints in robot.toml"
        )
    inverted = [
        f"{name} [{lower:g}, {upper:g}]"
        for name, lower, upper in zip(
            driven_joints(model), model.lowerPositionLimit, model.upperPositionLimit
        )
        if not lower <= upper
    ]
    if inverted:
        raise RobotDescriptionError(
            f"{source}: joint limits must have lower ≤ upper; inverted: {', '.join(inverted)}"
        )


@contextlib.contextmanager
def _captured_stderr() -> Iterator[Callable[[], list[str]]]:
    """Whatever C++ libraries (urdfdom) write to the process's stderr during the block, held back
    and given, as lines, by the function the block receives (after the block)."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as buffer:
        os.dup2(buffer.fileno(), 2)
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            buffer.seek(0)
            lines += buffer.read().decode(errors="replace").splitlines()


def _add_payload(model: pin.Model, frame: str, payload: float) -> None:
    """A point mass ``payload`` (kg) at the tool frame, carried by the tool's joint."""
    tool = model.frames[frame_id(model, frame)]
    point_mass = pin.Inertia(payload, tool.placement.translation, np.zeros((3, 3)))
    model.inertias[tool.parentJoint] = model.inertias[tool.parentJoint] + point_mass


def _tool(model: pin.Model, description: Description, where: str) -> str:
    """The tool frame: ``tool_frame``, a link, or ``tool = {link = "...", xyz = [...]}``, a
    point on a link, added to ``model`` as the frame "tool point"; by default the last link."""
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    tool = description.tool
    if tool is not None:
        if tool.link not in bodies:
            raise RobotDescriptionError(
                f"{where} tool.link = {tool.link!r} is not a link of the URDF; links: {bodies}"
            )
        parent_id = model.getFrameId(tool.link, pin.FrameType.BODY)
        parent = model.frames[parent_id]
        placement = parent.placement * pin.SE3(np.eye(3), np.array(tool.xyz))
        frame = pin.Frame(
            TOOL_POINT, parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME
        )
        model.addFrame(frame, False)
        return TOOL_POINT
    tool_frame = description.tool_frame or bodies[-1]
    if tool_frame not in bodies:
        raise RobotDescriptionError(
            f"{where}: tool frame {tool_frame!r} is not a link of the URDF; links: {bodies}"
        )
    return tool_frame


TOOL_POINT = "tool point"  # the frame of a tool given as a point on a link


def _actuators(
    root: etree._Element, description: Description, source: str, where: str, locked: list[str]
) -> list:
    """The declared actuators, from the URDF's transmissions and robot.toml's tables, less
    those on locked joints (dropped with a warning)."""
    declared = read_transmissions(root, source)
    declared += read_actuator_tables(description.actuators, where)
    dropped = [a.name for a in declared if a.joint in locked]
    if dropped:
        warnings.warn(f"actuators on locked joints are dropped: {', '.join(dropped)}", stacklevel=3)
    return [a for a in declared if a.joint not in locked]


STEP = np.radians(0.25)  # rad: the grid a continuous joint's stroke range is first sought on
BISECTIONS = 40  # halvings of a grid step that locate each end of the range (to 1e-14 rad)


def _stroke_arc(robot: Robot, column: int, row: int) -> tuple[float, float] | None:
    """The angles of joint ``column`` (rad) over which actuator ``row`` stays inside its
    stroke, the other joints at zero: sought on a grid over two turns either way, each end then
    located by bisection; of several arcs (a cylinder on either side of the joint axis), the
    one nearest the URDF's zero angle. None where the stroke admits no angle, or every one."""
    actuator = robot.actuators.maps[row]
    rest = np.clip(0.0, robot.lower, robot.upper)

    def inside(theta: np.ndarray) -> np.ndarray:
        q = np.repeat(rest[None], len(theta), axis=0)
        q[:, column] = theta
        x = robot.actuators.evaluate(robot.kinematics(q))[0][:, row]
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


def _bound_by_strokes(robot: Robot, continuous: list[str]) -> None:
    """Give each ``continuous`` joint whose actuator has a finite stroke the arc over which the
    actuator stays inside it (`_stroke_arc`: exact where the actuator spans that joint alone,
    as a cylinder between the links on either side of it does); where there is none, the
    joint stays unbounded (and `redundancy check` says so)."""
    for joint in continuous:
        column = robot.joint_names.index(joint)
        row = next(i for i, a in enumerate(robot.actuators) if a.index == column)
        stroke = robot.actuators.maps[row]
        arc = None
        if np.isfinite(stroke.lower) or np.isfinite(stroke.upper):
            arc = _stroke_arc(robot, column, row)
        if arc is not None:
            robot.model.lowerPositionLimit[column], robot.model.upperPositionLimit[column] = arc


def load_robot(
    robot: str | Path,
    payload: float | None = None,
    task_axes: str | None = None,
    hydraulics: str | Path | None = None,
) -> Robot:
    """Load a bundled robot by name, or a robot from a ``robot.toml``, ``.urdf`` or ``.xacro``
    path.

    A ``robot.toml`` names the URDF (``urdf``: a URDF or xacro file beside it, or
    ``package://<distribution>/<path>``), the tool (``tool_frame``, a link, or ``tool = {link
    = "...", xyz = [...]}``, a point on a link in m), the task axes (``task_axes``: world
    components of the tool position, e.g. "xz"), and optionally the actuators
    (``[actuators.<name>]`` tables, `redundancy.model.transmissions`), joints to lock
    (``locked_joints``: a list, at their neutral value, or a table {joint = value}, rad or m),
    a default payload in kg (``payload``) and the robot's task file (``task``, see
    `redundancy.planning.tasks`). A bare URDF or xacro takes its last link as the tool and the
    full position "xyz" as the task. ``payload`` (kg, ≥ 0) is a point mass at the tool frame,
    None taking the description's default, or 0; ``task_axes`` overrides the description's. The
    hydraulic circuit comes from the ``[hydraulics]`` table of the TOML file ``hydraulics`` if
    given, else from the description's (schema in the README).

    What the URDF lacks is said, not fatal: meshes no file answers are named in one warning
    (the playback then draws the links as rods between joint origins), and links without
    inertia in another (the robot is kinematic only: anything needing masses refuses). An
    ``<inertial>`` that is there must hold numbers a body can have (`_check_inertials`).
    """
    name, folder, description, where = _describe(robot)
    reference = description.urdf
    urdf_path = _urdf_path(folder, reference)
    if not urdf_path.is_file():
        raise RobotDescriptionError(f"{where}: urdf = {reference!r}: no such file {urdf_path}")
    source = urdf_path.name
    locked = description.locked_joints
    locked = dict(locked) if isinstance(locked, dict) else dict.fromkeys(locked)
    root, continuous = _intake(_urdf_text(urdf_path), source, locked)
    zero_masses = _check_inertials(root, source)
    missing_meshes = _resolve_meshes(root, urdf_path.parent)
    if missing_meshes:
        warnings.warn(
            f"{source}: meshes not found, the playback draws rods instead: "
            f"{', '.join(missing_meshes)}",
            stacklevel=2,
        )
    model = _lock(_build_model(root, source), locked, where, source)
    _check_joints(model, source)
    for joint in continuous:
        if joint not in locked:  # unbounded, unless its actuator's stroke bounds it (below)
            index = model.joints[model.getJointId(joint)].idx_q
            model.lowerPositionLimit[index], model.upperPositionLimit[index] = -np.inf, np.inf
    tool_frame = _tool(model, description, where)
    if task_axes is None:
        task_axes = description.task_axes
    if (
        not isinstance(task_axes, str)
        or not task_axes
        or any(a not in AXES for a in task_axes)
        or len(set(task_axes)) != len(task_axes)
    ):
        raise RobotDescriptionError(
            f"task_axes {task_axes!r} must be distinct letters among 'x', 'y', 'z'"
        )
    if payload is None:
        payload = description.payload
    else:
        payload = validate(Payload, {"payload": payload}, "load_robot").payload
    if payload > 0:
        _add_payload(model, tool_frame, payload)
    maps = _actuators(root, description, source, where, list(locked))
    actuators = ActuatorSet.bind(maps, model)
    task_file = None if description.task is None else folder / description.task
    actuator_names, rotary = actuators.names, actuators.rotary.tolist()
    declared = read_cylinders(root, source)
    table, origin = None, ""
    if hydraulics is not None:
        if not isinstance(hydraulics, str | os.PathLike):
            raise InvalidInputError(
                f"hydraulics must be the path of a TOML file with a [hydraulics] table; got "
                f"{type(hydraulics).__name__} {hydraulics!r}"[:240]
            )
        table, origin = read_hydraulics_file(Path(hydraulics)), str(hydraulics)
    elif description.hydraulics is not None:
        table, origin = description.hydraulics, where
    elif declared:
        warnings.warn(
            f"{source} declares cylinders {sorted(declared)} but no [hydraulics] table "
            "gives the machine's supply; hydraulics are off",
            stacklevel=2,
        )
    circuit = None
    if table is not None:
        circuit = circuit_from_table(table, origin, actuator_names, rotary, declared, source)
    loaded = Robot(
        name,
        model,
        tool_frame,
        task_axes,
        actuators,
        payload,
        urdf_path,
        task_file,
        circuit,
        etree.tostring(root, encoding="unicode"),
        tuple(missing_meshes),
        zero_masses,
    )
    _bound_by_strokes(loaded, [j for j in continuous if j not in locked])
    if loaded.kinematic_only:
        warnings.warn(
            f"{loaded.massless}; the robot is kinematic only (the velocity objective, playback "
            "and check work; anything needing masses refuses)",
            stacklevel=2,
        )
    return loaded
