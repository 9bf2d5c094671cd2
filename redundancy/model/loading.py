"""Loading robots: bundled names, ``robot.toml`` descriptions and URDFs, with their actuators.

This is the only module that builds Pinocchio models (`load_robot`).
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import importlib.resources
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
from redundancy.model.actuators import ActuatorSet
from redundancy.model.hydraulics import circuit_from_table, read_hydraulics_file
from redundancy.model.robot import AXES, Robot
from redundancy.model.transmissions import read_cylinders, read_transmissions
from redundancy.model.values import MAX_PAYLOAD, names, number, read_toml, text


def bundled_root() -> Path:
    """Folder holding the bundled robots (``robots/`` in the source tree)."""
    return Path(str(importlib.resources.files("redundancy.robots")))


def bundled_robots() -> list[str]:
    """Names of the bundled robots: the folders of `bundled_root` with a ``robot.toml``."""
    return sorted(p.parent.name for p in bundled_root().glob("*/robot.toml"))


def _read_description(path: Path) -> dict:
    description = read_toml(path, "robot description")
    missing = [key for key in ("urdf", "tool_frame", "task_axes") if key not in description]
    if missing:
        raise RobotDescriptionError(f"{path}: missing keys {missing}")
    return description


def _describe(robot: str | Path) -> tuple[str, Path, dict, str]:
    """Name, folder, description (robot.toml contents) and where the description came from, of
    a bundled name or a file path."""
    if not isinstance(robot, str | Path):
        raise InvalidInputError(f"robot must be a name or a path; got {robot!r}")
    path = Path(robot)
    if path.suffix == ".urdf":
        if not path.is_file():
            raise RobotDescriptionError(f"no URDF file at {path}")
        return path.stem, path.parent, {"urdf": path.name}, str(path)
    if path.suffix == ".toml":
        if not path.is_file():
            raise RobotDescriptionError(f"no robot description at {path}")
        return path.parent.name, path.parent, _read_description(path), str(path)
    names = bundled_robots()
    if str(robot) not in names:
        raise RobotDescriptionError(
            f"unknown robot {str(robot)!r}; bundled robots: {', '.join(names)}; "
            "or give the path of a .urdf or robot.toml file"
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


def _build_model(urdf_path: Path, locked: list[str]) -> tuple[pin.Model, etree._Element]:
    """The Pinocchio model of a URDF, with the ``locked`` joints fixed at their neutral value,
    and the URDF's XML root."""
    try:
        tree = etree.parse(str(urdf_path))
    except (OSError, etree.XMLSyntaxError) as error:
        raise RobotDescriptionError(f"{urdf_path}: not readable XML: {error}") from error
    failure: Exception | None = None
    with _captured_stderr() as said:
        try:
            model = pin.buildModelFromUrdf(str(urdf_path))
        except (ValueError, RuntimeError) as error:
            failure = error
    if failure is not None:
        reason = next((line for line in said() if line.strip()), str(failure).splitlines()[0])
        raise RobotDescriptionError(
            f"{urdf_path}: not a valid URDF: {reason.strip().removeprefix('Error:').strip()}"
        ) from None
    joints = list(model.names)[1:]
    unknown = [j for j in locked if j not in joints]
    if unknown:
        raise RobotDescriptionError(
            f"locked joints {unknown} are not joints of {urdf_path.name}; joints: {joints}"
        )
    if locked:
        ids = [model.getJointId(j) for j in locked]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    odd = [
        name
        for name, joint in zip(model.names[1:], model.joints[1:])
        if joint.nq != 1 or joint.nv != 1
    ]
    if odd:
        raise RobotDescriptionError(
            f"{urdf_path}: joints {odd} are not revolute or prismatic; the toolkit handles "
            "one-degree-of-freedom joints only (lock the others with locked_joints)"
        )
    inverted = [
        f"{name} [{lower:g}, {upper:g}]"
        for name, lower, upper in zip(
            model.names[1:], model.lowerPositionLimit, model.upperPositionLimit
        )
        if not lower <= upper
    ]
    if inverted:
        raise RobotDescriptionError(
            f"{urdf_path}: joint limits must have lower ≤ upper; inverted: {', '.join(inverted)}"
        )
    return model, tree.getroot()


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
    tool = model.frames[model.getFrameId(frame)]
    point_mass = pin.Inertia(payload, tool.placement.translation, np.zeros((3, 3)))
    model.inertias[tool.parentJoint] = model.inertias[tool.parentJoint] + point_mass


def load_robot(
    robot: str | Path,
    payload: float | None = None,
    task_axes: str | None = None,
    hydraulics: str | Path | None = None,
) -> Robot:
    """Load a bundled robot by name, or a robot from a ``robot.toml`` or ``.urdf`` path.

    A ``robot.toml`` names the URDF (``urdf``: a path beside it, or
    ``package://<distribution>/<path>``), the tool frame (``tool_frame``), the task axes
    (``task_axes``: world components of the tool position, e.g. "xz"), and optionally joints to
    lock at their neutral value (``locked_joints``), a default payload in kg (``payload``) and
    the robot's task file (``task``, see `redundancy.planning.tasks`). A bare URDF takes its last
    link as the tool and the full position "xyz" as the task. ``payload`` (kg, ≥ 0) is a point
    mass at the tool frame, None taking the description's default, or 0; ``task_axes``
    overrides the description's. The hydraulic circuit comes from the ``[hydraulics]`` table of
    the TOML file ``hydraulics`` if given, else from the description's (schema in the README).
    """
    name, folder, description, where = _describe(robot)
    reference = text(description, "urdf", where, "the URDF, beside this file or package://")
    urdf_path = _urdf_path(folder, reference)
    locked = names(description, "locked_joints", where, "joints fixed at their neutral value")
    model, root = _build_model(urdf_path, list(locked))
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    tool_frame = text(description, "tool_frame", where, "the tool's link", bodies[-1])
    if tool_frame not in bodies:
        raise RobotDescriptionError(
            f"tool frame {tool_frame!r} is not a link of {urdf_path.name}; links: {bodies}"
        )
    if task_axes is None:
        task_axes = text(description, "task_axes", where, "world axes of the task", AXES)
    if (
        not isinstance(task_axes, str)
        or not task_axes
        or any(a not in AXES for a in task_axes)
        or len(set(task_axes)) != len(task_axes)
    ):
        raise RobotDescriptionError(
            f"task_axes {task_axes!r} must be distinct letters among 'x', 'y', 'z'"
        )
    meaning = f"kg at the tool, 0 to {MAX_PAYLOAD:g}"
    if payload is None:
        payload = number(description, "payload", where, meaning, 0.0, 0.0, MAX_PAYLOAD)
    else:
        payload = number(
            {"payload": payload}, "payload", "load_robot", meaning, 0.0, 0.0, MAX_PAYLOAD
        )
    if payload > 0:
        _add_payload(model, tool_frame, payload)
    actuators = ActuatorSet.bind(read_transmissions(root, urdf_path.name), model)
    task = (
        text(description, "task", where, "the robot's task file", None)
        if "task" in description
        else None
    )
    task_file = None if task is None else folder / task
    actuator_names, rotary = actuators.names, actuators.rotary.tolist()
    declared = read_cylinders(root, urdf_path.name)
    table, source = None, ""
    if hydraulics is not None:
        table, source = read_hydraulics_file(Path(hydraulics)), str(hydraulics)
    elif "hydraulics" in description:
        table, source = description["hydraulics"], where
    elif declared:
        warnings.warn(
            f"{urdf_path.name} declares cylinders {sorted(declared)} but no [hydraulics] table "
            "gives the machine's supply; hydraulics are off",
            stacklevel=2,
        )
    circuit = None
    if table is not None:
        circuit = circuit_from_table(
            table, source, actuator_names, rotary, declared, urdf_path.name
        )
    return Robot(
        name, model, tool_frame, task_axes, actuators, payload, urdf_path, task_file, circuit
    )
