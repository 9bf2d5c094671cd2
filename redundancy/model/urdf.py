"""The URDF front end: a URDF (or xacro) file read, checked, and built into a Pinocchio model.

yourdfpy parses the document; Pinocchio's model graph builds the model from that parse, the
branch holding a joint that a mimic joint follows first, so that a mimic joint may follow a
joint on any branch. A bad element is said in one line: the file, the element as written and
what it must be. A continuous joint is one unbounded angle (rad), not Pinocchio's (cos, sin)
pair; a floating or planar joint is refused unless locked; a mimic joint following a locked
joint is locked too, where it follows.
"""

from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yourdfpy
from lxml import etree
from pinocchio import graph

from redundancy.errors import RobotDescriptionError
from redundancy.model.parameters import number_or_text
from redundancy.model.schema import EXCERPT, excerpt

FREE = ("floating", "planar")  # URDF joint types of a base that moves freely
LIMITED = ("revolute", "prismatic")  # URDF joint types that must give their <limit>
INERTIA = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")  # <inertia>'s attributes, kg·m²
INERTIA_TOLERANCE = 1e-6  # of the largest principal moment: what a file's rounding may cost


@dataclass(frozen=True)
class Urdf:
    """A URDF read: its XML ``root`` (meshes by absolute path), yourdfpy's ``parse``, the
    file's name ``source``, the mesh references no file answers and the links of mass 0."""

    root: etree._Element
    parse: yourdfpy.Robot
    source: str
    missing_meshes: tuple[str, ...]
    zero_masses: tuple[str, ...]

    @property
    def text(self) -> str:
        return etree.tostring(self.root, encoding="unicode")


def read_urdf(path: Path) -> Urdf:
    """The URDF of ``path`` (a ``.xacro`` file expanded by xacro), checked: XML, a ``<robot>``
    yourdfpy reads, `_check_tree` and `_check_inertials`."""
    source = path.name
    try:
        root = etree.fromstring(_document(path))
    except etree.XMLSyntaxError as error:
        raise RobotDescriptionError(f"{source}: not readable XML: {error}") from None
    if root.tag != "robot":
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: Could not find the 'robot' element"
        )
    zero_masses = _check_inertials(root, source)
    try:
        parse = yourdfpy.URDF.load(
            io.BytesIO(etree.tostring(root)), build_scene_graph=False, load_meshes=False
        ).robot
    except (KeyError, AttributeError, ValueError, IndexError, TypeError) as error:
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: {type(error).__name__}: {excerpt(str(error))}"
        ) from None
    _check_tree(parse, source)
    missing = _resolve_meshes(root, path.resolve().parent)
    return Urdf(root, parse, source, missing, zero_masses)


def _document(path: Path) -> bytes:
    """The URDF document of ``path`` (its encoding is the XML's to declare); a ``.xacro`` file
    is expanded by the xacro package. A YAML file the xacro loads is named with the line of its
    error, never quoted."""
    if path.suffix != ".xacro":
        try:
            return path.read_bytes()
        except OSError as error:
            raise RobotDescriptionError(f"{path}: not readable: {error.strerror}") from None
    import xacro
    import yaml

    try:
        said = io.StringIO()  # xacro's warnings: the error, if any, is said in one line
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return xacro.process_file(str(path)).toxml().encode()
    except Exception as error:  # xacro raises its own and its parsers' errors
        cause = getattr(error, "exc", None) or error.__cause__ or error.__context__
        if isinstance(cause, yaml.MarkedYAMLError) and cause.problem_mark is not None:
            mark = cause.problem_mark
            reason = f"{mark.name} line {mark.line + 1}: not YAML: {cause.problem}"
        else:
            lines = str(error).strip().splitlines()
            reason = f"{type(error).__name__}: {lines[0] if lines else ''}"
        raise RobotDescriptionError(f"{path}: xacro cannot expand it: {reason}") from error


def _check_tree(robot: yourdfpy.Robot, source: str) -> None:
    """Every joint joins two links of the URDF and a mimic joint follows a joint, one link is
    the root, and a revolute or prismatic joint gives its range, lower ≤ upper."""
    links, joints = {link.name for link in robot.links}, {joint.name for joint in robot.joints}
    for joint in robot.joints:
        where = f"{source}: not a valid URDF: joint {excerpt(joint.name)}"
        for end, name in (("parent", joint.parent), ("child", joint.child)):
            if name not in links:
                raise RobotDescriptionError(f"{where}: <{end} link={excerpt(name)}> is not a link")
        limit = joint.limit
        if joint.type in LIMITED and (limit is None or None in (limit.lower, limit.upper)):
            raise RobotDescriptionError(
                f'{where} is {joint.type}: it needs <limit lower="..." upper="..."/> (rad or m)'
            )
        if joint.mimic is not None and joint.mimic.joint not in joints:
            raise RobotDescriptionError(
                f"{where}: <mimic joint={excerpt(joint.mimic.joint)}> follows no joint of the URDF"
            )
    inverted = [
        f"{j.name[:EXCERPT]} [{j.limit.lower:g}, {j.limit.upper:g}]"
        for j in robot.joints
        if j.type in LIMITED and j.mimic is None and not j.limit.lower <= j.limit.upper
    ]
    if inverted:
        raise RobotDescriptionError(
            f"{source}: joint limits must have lower ≤ upper; inverted: {', '.join(inverted)}"
        )
    roots = sorted(links - {joint.child for joint in robot.joints})
    if len(roots) != 1:
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: it must have one root link, a link no joint is the "
            f"child of; it has {len(roots)}: {excerpt(roots)}"
        )


def build_model(urdf: Urdf, locked: dict[str, float | None]) -> tuple[pin.Model, list[str]]:
    """The Pinocchio model of ``urdf`` and its continuous joints (one coordinate each, rad, in
    [−π, π] where a value is chosen to lock them; the caller unbounds the others). A mimic joint
    following a ``locked`` joint is added to ``locked`` at multiplier · value + offset."""
    robot, model_graph = urdf.parse, graph.ModelGraph()
    for link in robot.links:
        model_graph.addBody(link.name, _inertia(link.inertial))
    leaders = {j.mimic.joint for j in robot.joints if j.mimic and j.name not in locked}
    for joint in sorted(robot.joints, key=lambda j: not _leads(robot, j, leaders)):
        mimic = joint.mimic
        if mimic is not None and mimic.joint in locked and joint.name not in locked:
            locked[joint.name] = mimic.multiplier * (locked[mimic.joint] or 0.0) + mimic.offset
            mimic = None
        kind, lower, upper = _joint(joint, urdf.source, locked)
        if mimic is not None:
            kind = graph.JointMimic(kind, mimic.joint, mimic.multiplier, mimic.offset)
        edge = model_graph.edgeBuilder().withName(joint.name).withJointType(kind)
        edge = edge.withSourceVertex(joint.parent).withTargetVertex(joint.child)
        edge = edge.withSourcePose(_placement(joint.origin)).withTargetPose(pin.SE3.Identity())
        if kind.nq == 1 and mimic is None:
            edge = edge.withMinConfig(np.array([lower])).withMaxConfig(np.array([upper]))
        edge.build()
    root = next(iter({link.name for link in robot.links} - {j.child for j in robot.joints}))
    try:
        model = graph.buildModel(model_graph, root, pin.SE3.Identity())
    except (ValueError, RuntimeError) as error:
        raise RobotDescriptionError(
            f"{urdf.source}: not a valid URDF: {pinocchio_message(error)}"
        ) from None
    return model, [j.name for j in robot.joints if j.type == "continuous"]


def _leads(robot: yourdfpy.Robot, joint: yourdfpy.Joint, leaders: set[str]) -> bool:
    """Whether ``joint`` or a joint below it is among the ``leaders`` (joints mimic joints
    follow): its branch is built first."""
    below = [j for j in robot.joints if j.parent == joint.child]
    return joint.name in leaders or any(_leads(robot, j, leaders) for j in below)


JOINTS = {  # URDF joint types: the model graph's joint of an axis (unit vector)
    "revolute": graph.JointRevolute,
    "continuous": graph.JointRevolute,
    "prismatic": graph.JointPrismatic,
    "fixed": lambda axis: graph.JointFixed(),
    "floating": lambda axis: graph.JointFreeFlyer(),
    "planar": lambda axis: graph.JointPlanar(),
}


def _joint(joint: yourdfpy.Joint, source: str, locked: dict) -> tuple[Any, float, float]:
    """The model graph's joint of a URDF joint, and its range (rad or m; [−π, π] for a
    continuous joint)."""
    where = f"{source}: joint {excerpt(joint.name)}"
    if joint.type not in JOINTS:
        raise RobotDescriptionError(
            f"{where}: type={excerpt(joint.type)} must be one of {', '.join(JOINTS)}"
        )
    axis = np.asarray(joint.axis, dtype=float)
    moves = joint.type in ("revolute", "continuous", "prismatic")
    if moves and not (np.all(np.isfinite(axis)) and np.linalg.norm(axis) > 0):
        raise RobotDescriptionError(
            f"{where}: <axis xyz={excerpt(' '.join(map(str, axis)))}> must be three finite "
            "numbers, not all zero"
        )
    if joint.type in FREE and joint.name not in locked:
        raise RobotDescriptionError(
            f"{where} is {joint.type}, a base that moves freely; the toolkit models machines on "
            f'a fixed base: add locked_joints = ["{joint.name}"] to robot.toml (the base stays '
            'at the joint\'s origin) or make it type="fixed"'
        )
    kind = JOINTS[joint.type](axis / np.linalg.norm(axis) if moves else axis)
    if joint.type in LIMITED:
        return kind, joint.limit.lower, joint.limit.upper
    return kind, -math.pi, math.pi  # the range of a continuous joint; others have none


def _placement(transform: np.ndarray | None) -> pin.SE3:
    """A URDF ``<origin>`` (yourdfpy's 4 × 4 transform, None for none) as an SE3."""
    return pin.SE3(np.eye(4) if transform is None else transform)


def _inertia(inertial: yourdfpy.Inertial | None) -> pin.Inertia:
    """A link's spatial inertia: its mass at the ``<inertial>``'s origin, its rotational inertia
    turned from the origin's axes into the link's, I = R I' Rᵀ; none without an inertial."""
    if inertial is None or inertial.mass is None:
        return pin.Inertia.Zero()
    placement = _placement(inertial.origin)
    moments = placement.rotation @ inertial.inertia @ placement.rotation.T
    return pin.Inertia(inertial.mass, placement.translation, moments)


def pinocchio_message(error: Exception) -> str:
    """The one line an error of Pinocchio (or of its mesh loader) means: its message, without
    where in Pinocchio's sources it was raised."""
    text = str(error)
    head, found, message = text.partition("message:")
    lines = [line.strip() for line in (message if found else head).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__


def _inertial_values(
    inertial: etree._Element,
    tag: str,
    attributes: tuple[str, ...],
    where: str,
    meaning: str,
    default: str | None = None,
    lower: float = -math.inf,
) -> np.ndarray:
    """The finite numbers ≥ ``lower`` the ``attributes`` of the ``<inertial>``'s child ``tag``
    hold, one each (as many as ``default`` holds where given: the text of an attribute left
    out, or of all where the child is); else one line: the link (``where``), the child as
    written and what it must be (``meaning``)."""
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
        raise RobotDescriptionError(f"{where} {written(element)} must be {meaning}")
    return np.array(values)


def written(element: etree._Element | None) -> str:
    """An element as written in the file, for a message."""
    return etree.tostring(element, encoding="unicode", with_tail=False)


def _check_inertials(root: etree._Element, source: str) -> tuple[str, ...]:
    """Every link's ``<inertial>`` holds numbers a body can have (a parser may drop one it
    cannot read without a word, or keep a negative mass): its origin finite, its mass finite
    and ≥ 0, its inertia a body's rotational inertia, symmetric positive semi-definite with
    each principal moment at most the sum of the other two (six entries make it symmetric;
    with the moments a ≤ b ≤ c, a + b ≥ c gives the rest), to `INERTIA_TOLERANCE`. Returns
    the links whose mass is 0."""
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
        entries = _inertial_values(inertial, "inertia", INERTIA, where, inertia)
        moments = np.linalg.eigvalsh(entries[[[0, 1, 2], [1, 3, 4], [2, 4, 5]]])
        if moments[0] + moments[1] < moments[2] - INERTIA_TOLERANCE * np.abs(moments).max():
            raise RobotDescriptionError(
                f"{where} {written(inertial.find('inertia'))} is not a body's rotational "
                f"inertia: its principal moments [{', '.join(f'{m:.4g}' for m in moments)}] "
                "kg·m² must be ≥ 0 and each at most the sum of the other two"
            )
    return tuple(zero_masses)


def _mesh_file(filename: str, folder: Path) -> Path | None:
    """The file a URDF mesh reference names, or None where no file answers: a path absolute,
    ``file://`` or relative to the URDF's ``folder``; ``package://<package>/<path>`` looked for
    in the URDF's folder and its ancestors as ``<path>`` (yourdfpy's rule: one of them is the
    package) or as ``<package>/<path>`` (a folder holding the package)."""
    names = dict.fromkeys(
        (
            yourdfpy.filename_handler_ignore_directive_package(filename),
            yourdfpy.filename_handler_ignore_directive(filename),
        )
    )
    folders = (folder, *folder.parents) if filename.startswith("package://") else (folder,)
    candidates = (directory / name for directory in folders for name in names)
    return next((c.resolve() for c in candidates if c.is_file()), None)


def _resolve_meshes(root: etree._Element, folder: Path) -> tuple[str, ...]:
    """Point every visual mesh of the URDF at its file, by absolute path, so that the text
    describes the robot on its own; return the references no file answers."""
    missing = []
    for mesh in root.findall("link/visual/geometry/mesh"):
        filename = mesh.get("filename", "")
        found = _mesh_file(filename, folder)
        if found is None:
            missing.append(filename)
        else:
            mesh.set("filename", str(found))
    return tuple(dict.fromkeys(missing))
