"""The URDF front end: a URDF (or xacro) file read, checked, and built into a Pinocchio model.

yourdfpy parses the document; Pinocchio's model graph builds the model from that parse, a
branch holding a joint that a mimic joint on another branch follows before that branch, so that
a mimic joint may follow a joint on any branch (`_build_order`). A bad element is said in one
line: the file, the element as written and what it must be. A continuous joint is one unbounded
angle (rad), not Pinocchio's (cos, sin) pair; a floating or planar joint is refused unless
locked; a mimic joint following a locked joint is locked too, where it follows.
"""

from __future__ import annotations

import contextlib
import io
import math
import warnings
from collections import Counter
from collections.abc import Mapping
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
from redundancy.model.values import MAX_INERTIA, MAX_LINK_MASS

FREE = ("floating", "planar")  # URDF joint types of a base that moves freely
LIMITED = ("revolute", "prismatic")  # URDF joint types that must give their <limit>
MOVING = ("revolute", "continuous", "prismatic")  # URDF joint types of one coordinate
INERTIA = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")  # <inertia>'s attributes, kg·m²
ORIGIN = 'xyz="x y z" rpy="r p y", three finite numbers each (m, rad)'
INERTIA_TOLERANCE = 1e-6  # of the largest principal moment: what a file's rounding may cost


@dataclass(frozen=True)
class Urdf:
    """A URDF read: its XML ``root`` (meshes by absolute path), yourdfpy's ``parse``, the
    file's path ``source``, the mesh references no file answers and the links of mass 0."""

    root: etree._Element
    parse: yourdfpy.Robot
    source: str
    missing_meshes: tuple[str, ...]
    zero_masses: tuple[str, ...]
    mimics: dict[str, tuple[str, float, float]]  # `mimics`: each mimic joint's leader, a, b

    @property
    def text(self) -> str:
        return etree.tostring(self.root, encoding="unicode")


def read_urdf(path: Path) -> Urdf:
    """The URDF of ``path`` (a ``.xacro`` file expanded by xacro), checked: XML, a ``<robot>``
    with `_check_inertials` and `_check_joints`, which yourdfpy reads, and `_check_tree`.
    Messages name the file by ``path``, and bad XML by its line too."""
    source = str(path)
    try:
        root = etree.fromstring(_document(path))
    except etree.XMLSyntaxError as error:
        line, column = error.position  # which the parser's message ends with: named once, first
        said = error.msg.removesuffix(f", line {line}, column {column}")
        raise RobotDescriptionError(f"{source} line {line}: not readable XML: {said}") from None
    if root.tag != "robot":
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: Could not find the 'robot' element"
        )
    zero_masses = _check_inertials(root, source)
    _check_joints(root, source)
    try:
        parse = yourdfpy.URDF.load(
            io.BytesIO(etree.tostring(root)), build_scene_graph=False, load_meshes=False
        ).robot
    except (KeyError, AttributeError, ValueError, IndexError, TypeError) as error:
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: {type(error).__name__}: {excerpt(str(error))}"
        ) from None
    followed = _check_tree(parse, source)
    missing = _resolve_meshes(root, path.resolve().parent)
    return Urdf(root, parse, source, missing, zero_masses, followed)


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


def _check_tree(robot: yourdfpy.Robot, source: str) -> dict[str, tuple[str, float, float]]:
    """Every joint is of a URDF type and joins two links of the URDF, each link is the child
    of one joint at most, one link is the root and every other hangs from it (no cycle), a
    revolute or prismatic joint gives its range, lower ≤ upper, and a mimic joint follows a
    joint it can follow; returns `mimics`."""
    links, joints = {link.name for link in robot.links}, {joint.name for joint in robot.joints}
    for joint in robot.joints:
        if joint.type not in JOINTS:
            raise RobotDescriptionError(
                f"{source}: joint {excerpt(joint.name)}: type={excerpt(joint.type)} must be one "
                f"of {', '.join(JOINTS)}"
            )
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
    parents: dict[str, list[str]] = {}  # the joints each link is the child of
    for joint in robot.joints:
        parents.setdefault(joint.child, []).append(joint.name)
    for link, above in parents.items():
        if len(above) > 1:
            raise RobotDescriptionError(
                f"{source}: not a valid URDF: link {excerpt(link)} is the child of "
                f"{len(above)} joints, {excerpt(above)}; a link hangs from one joint (a closed "
                "chain is declared as an actuator, not as a second joint)"
            )
    roots = sorted(links - set(parents))
    if len(roots) != 1:
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: it must have one root link, a link no joint is the "
            f"child of; it has {len(roots)}: {excerpt(roots)}"
        )
    children: dict[str, list[str]] = {}  # the links hanging from each link
    for joint in robot.joints:
        children.setdefault(joint.parent, []).append(joint.child)
    hanging, below = set(roots), [roots[0]]  # the links reached from the root, down the joints
    while below:
        for child in children.get(below.pop(), []):
            if child not in hanging:
                hanging.add(child)
                below.append(child)
    if hanging != links:
        cycle = [j.name for j in robot.joints if j.child not in hanging]
        raise RobotDescriptionError(
            f"{source}: not a valid URDF: joints {excerpt(cycle)} form a cycle that does not "
            f"hang from the root link {roots[0]!r}; a URDF is a tree"
        )
    return mimics(robot, source)


def mimics(robot: yourdfpy.Robot, source: str) -> dict[str, tuple[str, float, float]]:
    """Each mimic joint's leader (a joint that mimics none), multiplier a and offset b, q = a ·
    q_leader + b: a mimic of a mimic follows its leader's leader, a = a₁a₂, b = a₁b₂ + b₁. A
    leader moves along one coordinate (revolute, continuous or prismatic), and sits on another
    branch or above its follower: Pinocchio builds a leader before the joints that follow it."""
    joints = {joint.name: joint for joint in robot.joints}
    above = {joint.child: joint.name for joint in robot.joints}  # the joint above each link
    found = {}
    for joint in (j for j in robot.joints if j.mimic is not None):
        where = f"{source}: joint {excerpt(joint.name)} <mimic joint={excerpt(joint.mimic.joint)}>"
        multiplier, offset, chain = 1.0, 0.0, [joint.name]
        leader = joint
        while leader.mimic is not None:
            mimic = leader.mimic
            multiplier, offset = multiplier * mimic.multiplier, multiplier * mimic.offset + offset
            leader = joints[mimic.joint]
            if leader.name in chain:
                raise RobotDescriptionError(
                    f"{where}: the mimic joints {excerpt(chain)} follow one another in a circle; "
                    "one of them must follow a joint that mimics none"
                )
            chain.append(leader.name)
        if leader.type not in MOVING:
            raise RobotDescriptionError(
                f"{where} follows a {leader.type} joint, {excerpt(leader.name)}; a mimic joint "
                f"follows a {', '.join(MOVING[:-1])} or {MOVING[-1]} joint"
            )
        branch, link = set(), leader.parent  # the joints above the leader
        while link in above:
            branch.add(above[link])
            link = joints[above[link]].parent
        if joint.name in branch:
            turned = (
                f': make {excerpt(leader.name)} follow it instead, <mimic joint="{joint.name}" '
                f'multiplier="{1 / multiplier:.12g}" offset="{0.0 - offset / multiplier:.12g}"/>'
                if multiplier
                else ""
            )
            raise RobotDescriptionError(
                f"{where} follows {excerpt(leader.name)}, a joint below it on its branch; "
                f"Pinocchio builds a leader before the joints that follow it{turned}"
            )
        found[joint.name] = (leader.name, multiplier, offset)
    return found


def build_model(urdf: Urdf, locked: dict[str, float | None]) -> tuple[pin.Model, list[str]]:
    """The Pinocchio model of ``urdf`` and its continuous joints (one coordinate each, rad, in
    [−π, π] where a value is chosen to lock them; the caller unbounds the others). A joint of
    one coordinate ``locked`` without a value is locked at rest: 0, or the end of its range
    nearest it; one whose range is one value (lower = upper) is added to ``locked`` there, with
    a warning. A mimic joint following a locked joint is added to ``locked`` at multiplier ·
    value + offset."""
    robot, model_graph = urdf.parse, graph.ModelGraph()
    stuck = [
        j
        for j in robot.joints
        if j.type in LIMITED
        and j.mimic is None
        and j.name not in locked
        and j.limit.lower == j.limit.upper
    ]
    if stuck:
        warnings.warn(
            f"{urdf.source}: joints whose range is one value (lower = upper) are locked there: "
            + ", ".join(f"{j.name} = {j.limit.lower:g}" for j in stuck),
            stacklevel=3,
        )
        locked |= {j.name: j.limit.lower for j in stuck}
    for joint in robot.joints:
        if joint.name in locked and locked[joint.name] is None and joint.type in MOVING:
            ends = (joint.limit.lower, joint.limit.upper) if joint.type in LIMITED else (-1, 1)
            locked[joint.name] = float(np.clip(0.0, *ends))
    for link in robot.links:
        model_graph.addBody(link.name, _inertia(link.inertial))
    followed = urdf.mimics
    root = next(iter({link.name for link in robot.links} - {j.child for j in robot.joints}))
    for joint in _build_order(robot, root, followed, locked, urdf.source):
        mimic = followed.get(joint.name)
        if mimic is not None and mimic[0] in locked and joint.name not in locked:
            leader, multiplier, offset = mimic
            locked[joint.name] = multiplier * (locked[leader] or 0.0) + offset
        if joint.name in locked:
            mimic = None
        kind, lower, upper = _joint(joint, urdf.source, locked)
        if mimic is not None:
            kind = graph.JointMimic(kind, *mimic)
        edge = model_graph.edgeBuilder().withName(joint.name).withJointType(kind)
        edge = edge.withSourceVertex(joint.parent).withTargetVertex(joint.child)
        edge = edge.withSourcePose(_placement(joint.origin)).withTargetPose(pin.SE3.Identity())
        if kind.nq == 1 and mimic is None:
            edge = edge.withMinConfig(np.array([lower])).withMaxConfig(np.array([upper]))
        edge.build()
    try:
        model = graph.buildModel(model_graph, root, pin.SE3.Identity())
    except (ValueError, RuntimeError) as error:
        raise RobotDescriptionError(
            f"{urdf.source}: not a valid URDF: {pinocchio_message(error)}"
        ) from None
    return model, [j.name for j in robot.joints if j.type == "continuous"]


def _build_order(
    robot: yourdfpy.Robot,
    root: str,
    followed: Mapping[str, tuple[str, float, float]],
    locked: Mapping[str, float | None],
    source: str,
) -> list[yourdfpy.Joint]:
    """The joints in the order the model is built: depth first from the ``root`` link, a
    branch whole before the next (Pinocchio numbers a branch's joints together), each link's
    branches in the file's order, except that where a mimic joint (not locked, nor its leader)
    follows a joint on another branch, the branch holding the leader comes first where the two
    part. One line where two branches each hold the leader of a mimic joint on the other."""
    joints = {joint.name: joint for joint in robot.joints}
    above = {joint.child: joint.name for joint in robot.joints}  # the joint above each link

    def path(name: str | None) -> list[str]:  # the joints from the root down to ``name``
        found = []
        while name is not None:
            found.append(name)
            name = above.get(joints[name].parent)
        return found[::-1]

    after: dict[str, dict[str, str]] = {}  # a branch's first joint: those before it, and why
    for name, (leader, _, _) in followed.items():
        if name in locked or leader in locked:
            continue
        parted = next(
            ((own, other) for own, other in zip(path(name), path(leader)) if own != other), None
        )
        if parted is not None:  # the two branches part at a link: the leader's goes first
            after.setdefault(parted[0], {})[parted[1]] = name
    order: list[yourdfpy.Joint] = []
    pending = [[j.name for j in robot.joints if j.parent == root]]  # per link, depth first
    while pending:
        siblings = pending[-1]
        if not siblings:
            pending.pop()
            continue
        ready = next((j for j in siblings if not set(after.get(j, ())) & set(siblings)), None)
        if ready is None:
            waiting = sorted(
                {after[j][k] for j in siblings for k in after.get(j, ()) if k in siblings}
            )
            raise RobotDescriptionError(
                f"{source}: the mimic joints {', '.join(map(excerpt, waiting))} follow joints on "
                f"one another's branches (from link {excerpt(joints[siblings[0]].parent)}); a "
                "model builds one branch whole before the next, so one of them must follow a "
                "joint on its own branch, above it, or on a third branch"
            )
        siblings.remove(ready)
        order.append(joints[ready])
        pending.append([j.name for j in robot.joints if j.parent == joints[ready].child])
    return order


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
    axis = np.asarray(joint.axis, dtype=float)
    moves = joint.type in MOVING
    if moves and not np.linalg.norm(axis) > 0:  # finite: `_check_joints`
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
    turned from the origin's axes into the link's, I = R I' Rᵀ, a principal moment rounded
    below 0 taken as 0; none without an inertial."""
    if inertial is None or inertial.mass is None:
        return pin.Inertia.Zero()
    placement = _placement(inertial.origin)
    moments = placement.rotation @ inertial.inertia @ placement.rotation.T
    eigenvalues, axes = np.linalg.eigh(moments)
    if eigenvalues[0] < 0:  # a file's rounding (`_check_inertials`), which no body has
        moments = axes @ np.diag(np.maximum(eigenvalues, 0.0)) @ axes.T
    return pin.Inertia(inertial.mass, placement.translation, moments)


def pinocchio_message(error: Exception) -> str:
    """The one line an error of Pinocchio (or of its mesh loader) means: its message, without
    where in Pinocchio's sources it was raised."""
    text = str(error)
    head, found, message = text.partition("message:")
    lines = [line.strip() for line in (message if found else head).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__


def _numbers(
    parent: etree._Element,
    tag: str,
    attributes: Mapping[str, str | None],
    where: str,
    meaning: str,
    lower: float = -math.inf,
    upper: float = math.inf,
) -> np.ndarray:
    """The finite numbers in [``lower``, ``upper``] the ``attributes`` of ``parent``'s child
    ``tag`` hold:
    as many each as its default holds (the text an attribute left out, or the child, stands
    for), one where it has none and must be given; else one line: the element (``where``),
    the child as written and what it must be (``meaning``)."""
    element = parent.find(tag)
    if element is None and None in attributes.values():
        raise RobotDescriptionError(
            f"{where}: <{parent.tag}> has no <{tag}>; it needs one: {meaning}"
        )
    given = {} if element is None else dict(element.attrib)
    values = []
    for name, default in attributes.items():
        numbers = [number_or_text(v) for v in (given.get(name, default) or "").split()]
        if len(numbers) != (1 if default is None else len(default.split())) or not all(
            isinstance(v, float) and math.isfinite(v) and lower <= v <= upper for v in numbers
        ):
            raise RobotDescriptionError(f"{where} {written(element)} must be {meaning}")
        values += numbers
    return np.array(values)


def written(element: etree._Element | None) -> str:
    """An element as written in the file, for a message."""
    return etree.tostring(element, encoding="unicode", with_tail=False)


def _check_inertials(root: etree._Element, source: str) -> tuple[str, ...]:
    """Every link's ``<inertial>`` holds numbers a body can have (a parser may drop one it
    cannot read without a word, or keep a negative mass): its origin finite, its mass within
    [0, `MAX_LINK_MASS`], its inertia's entries within ±`MAX_INERTIA` and a body's rotational
    inertia, symmetric positive semi-definite with each principal moment at most the sum of the
    other two (six entries make it symmetric; with the moments a ≤ b ≤ c, a + b ≥ c gives the
    rest), to `INERTIA_TOLERANCE`. Returns the links whose mass is 0."""
    zero_masses = []
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        where = f"{source}: link {link.get('name')!r}"
        _numbers(inertial, "origin", dict.fromkeys(("xyz", "rpy"), "0 0 0"), where, ORIGIN)
        mass = f"a number within [0, {MAX_LINK_MASS:g}] (the link's mass, kg)"
        if _numbers(inertial, "mass", {"value": None}, where, mass, 0.0, MAX_LINK_MASS)[0] == 0:
            zero_masses.append(link.get("name"))
        inertia = (
            f"six numbers {', '.join(INERTIA)} within ±{MAX_INERTIA:g} (kg·m², about the centre "
            "of mass)"
        )
        entries = _numbers(
            inertial, "inertia", dict.fromkeys(INERTIA), where, inertia, -MAX_INERTIA, MAX_INERTIA
        )
        moments = np.linalg.eigvalsh(entries[[[0, 1, 2], [1, 3, 4], [2, 4, 5]]])
        if moments[0] + moments[1] < moments[2] - INERTIA_TOLERANCE * np.abs(moments).max():
            raise RobotDescriptionError(
                f"{where} {written(inertial.find('inertia'))} is not a body's rotational "
                f"inertia: its principal moments [{', '.join(f'{m:.4g}' for m in moments)}] "
                "kg·m² must be ≥ 0 and each at most the sum of the other two"
            )
    return tuple(zero_masses)


def _check_joints(root: etree._Element, source: str) -> None:
    """Every link and joint has a name of its own, every joint names its parent and child links,
    and its ``<origin>``, ``<axis>``, ``<limit>`` range and ``<mimic>`` hold finite numbers, as
    many as they must (a parser may drop what it cannot read, or keep a NaN)."""
    for kind in ("link", "joint"):
        names = [element.get("name") for element in root.findall(kind)]
        if None in names:
            raise RobotDescriptionError(
                f'{source}: not a valid URDF: a <{kind}> has no name="..."; each needs its own'
            )
        twice = sorted(name for name, count in Counter(names).items() if count > 1)
        if twice:
            raise RobotDescriptionError(
                f"{source}: not a valid URDF: {kind} names must differ; given more than once: "
                f"{excerpt(twice)}"
            )
    for joint in root.findall("joint"):
        where = f"{source}: joint {joint.get('name')!r}"
        for end in ("parent", "child"):
            if joint.find(end) is None or joint.find(end).get("link") is None:
                raise RobotDescriptionError(f'{where}: it needs <{end} link="..."/>')
        _numbers(joint, "origin", dict.fromkeys(("xyz", "rpy"), "0 0 0"), where, ORIGIN)
        _numbers(joint, "axis", {"xyz": "1 0 0"}, where, 'xyz="x y z", three finite numbers')
        limit = joint.find("limit")
        if limit is not None:
            given = {a: "0" for a in ("lower", "upper") if a in limit.attrib}
            _numbers(joint, "limit", given, where, "finite numbers lower and upper (rad or m)")
        _numbers(
            joint,
            "mimic",
            {"multiplier": "1", "offset": "0"},
            where,
            "finite numbers multiplier and offset (q = multiplier · q_joint + offset)",
        )


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
