"""`Robot` and `load_robot`: a URDF, its actuators and its task, with Pinocchio underneath.

This is the only module that builds Pinocchio models. Every joint-space quantity comes from
Pinocchio: positions and world-aligned frame Jacobians (and their rates) of the tool and of
every actuator attachment point (`Kinematics`), the mass matrix M(q) (CRBA), the nonlinear terms
N(q, v) = V(q, v) + G(q) and inverse dynamics (RNEA).

Configurations come one at a time, shape (n,), or as a batch, shape (k, n); every method
answers in the same form, with the batch axis first.
"""

from __future__ import annotations

import importlib.metadata
import importlib.resources
import tomllib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from lxml import etree

from redundancy.actuators import ActuatorSet
from redundancy.errors import InvalidInputError, RobotDescriptionError
from redundancy.transmissions import read_transmissions

AXES = "xyz"


def bundled_root() -> Path:
    """Folder holding the bundled robots (``robots/`` in the source tree)."""
    return Path(str(importlib.resources.files("redundancy.robots")))


def bundled_robots() -> list[str]:
    """Names of the bundled robots: the folders of `bundled_root` with a ``robot.toml``."""
    return sorted(p.parent.name for p in bundled_root().glob("*/robot.toml"))


class PointMotion(NamedTuple):
    """A point fixed on a link, for a batch of k states (world frame).

    position (k, 3) in m; jacobian (k, 3, n) = ∂p/∂q; with velocities also
    velocity (k, 3) = J_p v in m/s and jacobian_rate (k, 3, n) = dJ_p/dt.
    """

    position: np.ndarray
    jacobian: np.ndarray
    velocity: np.ndarray | None
    jacobian_rate: np.ndarray | None


@dataclass(frozen=True)
class Kinematics:
    """Pinocchio's kinematics of the robot's tracked points at a batch of k states.

    positions (k, F, 3) and jacobians (k, F, 3, n) of the F tracked frames (the tool and every
    actuator attachment point), world-aligned; with velocities v (k, n) also their velocities
    (k, F, 3) and jacobian_rates (k, F, 3, n). ``slots`` maps a Pinocchio frame id to its index F.
    """

    q: np.ndarray
    v: np.ndarray | None
    positions: np.ndarray
    jacobians: np.ndarray
    velocities: np.ndarray | None
    jacobian_rates: np.ndarray | None
    slots: dict[int, int]

    def point(self, frame: int) -> PointMotion:
        """Motion of the tracked frame ``frame``."""
        i = self.slots[frame]
        return PointMotion(
            self.positions[:, i],
            self.jacobians[:, i],
            None if self.velocities is None else self.velocities[:, i],
            None if self.jacobian_rates is None else self.jacobian_rates[:, i],
        )


def _as_batch(name: str, values: np.ndarray | list[float], n: int) -> tuple[np.ndarray, bool]:
    """``values`` as a (k, n) float array and whether it came as one (n,) vector."""
    array = np.asarray(values, dtype=float)
    single = array.ndim == 1
    if array.ndim not in (1, 2) or array.shape[-1] != n:
        raise InvalidInputError(f"{name} must have shape ({n},) or (k, {n}); got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f"{name} contains NaN or infinite values: {array.tolist()}")
    return np.atleast_2d(array), single


def _answer(batch: np.ndarray, single: bool) -> np.ndarray:
    return batch[0] if single else batch


class Robot:
    """A manipulator: Pinocchio model, tool point, task axes, actuators and limits.

    The task y is the tool position's world components ``task_axes`` (m of them); n joints; one
    actuator per joint (``actuators``), so that A = ∂x/∂q is square.
    """

    def __init__(
        self,
        name: str,
        model: pin.Model,
        tool_frame: str,
        task_axes: str,
        actuators: ActuatorSet,
        payload: float,
        urdf: Path,
        task_file: Path | None = None,
    ) -> None:
        self.name = name
        self.model = model
        self.data = model.createData()
        self.payload = payload
        self.urdf = urdf
        self.task_file = task_file
        self.tool_frame = tool_frame
        self.task_axes = task_axes
        self.actuators = actuators
        self._tool = model.getFrameId(tool_frame)
        self._task_rows = [AXES.index(a) for a in task_axes]
        tracked = [self._tool] + [f for a in actuators for f in a.frames]
        self._tracked = list(dict.fromkeys(tracked))
        self._slots = {frame: i for i, frame in enumerate(self._tracked)}
        self._lower_triangle = np.tril_indices(model.nv, -1)

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, n={self.n}, m={self.m}, payload={self.payload} kg)"

    @property
    def n(self) -> int:
        """Number of joints (= actuators)."""
        return self.model.nv

    @property
    def m(self) -> int:
        """Dimension of the task."""
        return len(self._task_rows)

    @cached_property
    def joint_names(self) -> list[str]:
        return list(self.model.names)[1:]

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits (n,), rad or m."""
        return self.model.lowerPositionLimit

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits (n,), rad or m."""
        return self.model.upperPositionLimit

    def configuration(self, q: np.ndarray | list[float], name: str = "q") -> np.ndarray:
        """``q`` as a checked (k, n) array: right shape, finite."""
        return _as_batch(name, q, self.n)[0]

    def kinematics(self, q: np.ndarray, v: np.ndarray | None = None) -> Kinematics:
        """Pinocchio's kinematics of the tracked points at the states (q, v), each (k, n)."""
        model, data, frames = self.model, self.data, self._tracked
        world = pin.LOCAL_WORLD_ALIGNED
        gathered, placed, changing = [], [], []
        for i in range(len(q)):
            if v is None:
                pin.computeJointJacobians(model, data, q[i])
            else:
                pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
            for frame in frames:
                gathered.append(pin.getFrameJacobian(model, data, frame, world))
                # updateFramePlacement hands back data.oMf[frame], faster than indexing it; its
                # translation is a view into data, hence the copy
                placed.append(pin.updateFramePlacement(model, data, frame).translation.copy())
                if v is not None:
                    changing.append(pin.getFrameJacobianTimeVariation(model, data, frame, world))
        shape = (len(q), len(frames))
        jacobians = np.array(gathered).reshape(*shape, 6, model.nv)[:, :, :3]
        positions = np.array(placed).reshape(*shape, 3)
        rates = None if v is None else np.array(changing).reshape(*shape, 6, model.nv)[:, :, :3]
        velocities = None if v is None else jacobians @ v[:, None, :, None]
        return Kinematics(
            q,
            v,
            positions,
            jacobians,
            None if velocities is None else velocities[..., 0],
            rates,
            self._slots,
        )

    def tool(self, kinematics: Kinematics) -> PointMotion:
        """Motion of the tool point, all three world components."""
        return kinematics.point(self._tool)

    def task(self, kinematics: Kinematics) -> PointMotion:
        """Task coordinates y (k, m), task Jacobian J (k, m, n) and, with v, ẏ and J̇ (Eqs. 6-8)."""
        tool = self.tool(kinematics)
        rows = self._task_rows
        return PointMotion(
            tool.position[:, rows],
            tool.jacobian[:, rows],
            None if tool.velocity is None else tool.velocity[:, rows],
            None if tool.jacobian_rate is None else tool.jacobian_rate[:, rows],
        )

    def fk(self, q: np.ndarray | list[float]) -> np.ndarray:
        """Task coordinates y = h1(q) (Eq. 6), (m,) or (k, m), in m."""
        batch, single = _as_batch("q", q, self.n)
        return _answer(self.task(self.kinematics(batch)).position, single)

    def jacobian(self, q: np.ndarray | list[float]) -> np.ndarray:
        """Task Jacobian J = ∂y/∂q (Eq. 7), (m, n) or (k, m, n)."""
        batch, single = _as_batch("q", q, self.n)
        return _answer(self.task(self.kinematics(batch)).jacobian, single)

    def mass(self, q: np.ndarray | list[float]) -> np.ndarray:
        """Joint-space inertia matrix M(q) (Eq. 18) by CRBA, (n, n) or (k, n, n)."""
        batch, single = _as_batch("q", q, self.n)
        return _answer(self.mass_matrices(batch), single)

    def mass_matrices(self, q: np.ndarray) -> np.ndarray:
        """M(q) (k, n, n) for configurations q (k, n) already checked (`configuration`)."""
        out = np.empty((len(q), self.n, self.n))
        for i, qi in enumerate(q):
            out[i] = pin.crba(self.model, self.data, qi)  # the upper triangle is M's
        lower, upper = self._lower_triangle
        out[:, lower, upper] = out[:, upper, lower]
        return out

    def nonlinear(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """N(q, v) = V(q, v) + G(q) (Eq. 20), (n,) or (k, n), in N·m or N."""
        qb, single = _as_batch("q", q, self.n)
        vb, _ = _as_batch("v", v, self.n)
        out = np.array([pin.nonLinearEffects(self.model, self.data, a, b) for a, b in zip(qb, vb)])
        return _answer(out, single)

    def gravity(self, q: np.ndarray | list[float]) -> np.ndarray:
        """Gravity torques G(q) (Eq. 18), (n,) or (k, n)."""
        qb, single = _as_batch("q", q, self.n)
        out = np.array([pin.computeGeneralizedGravity(self.model, self.data, a) for a in qb])
        return _answer(out, single)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """τ = M(q) a + V(q, v) + G(q) (Eq. 18) by RNEA, (n,) or (k, n)."""
        qb, single = _as_batch("q", q, self.n)
        vb, _ = _as_batch("v", v, self.n)
        ab, _ = _as_batch("a", a, self.n)
        out = np.array(
            [pin.rnea(self.model, self.data, qi, vi, ai) for qi, vi, ai in zip(qb, vb, ab)]
        )
        return _answer(out, single)


def _read_description(path: Path) -> dict:
    try:
        with path.open("rb") as f:
            description = tomllib.load(f)
    except tomllib.TOMLDecodeError as error:
        raise RobotDescriptionError(f"{path}: not valid TOML: {error}") from error
    missing = [key for key in ("urdf", "tool_frame", "task_axes") if key not in description]
    if missing:
        raise RobotDescriptionError(f"{path}: missing keys {missing}")
    return description


def _describe(robot: str | Path) -> tuple[str, Path, dict]:
    """Name, folder and description (robot.toml contents) of a bundled name or a file path."""
    path = Path(robot)
    if path.suffix == ".urdf":
        if not path.is_file():
            raise RobotDescriptionError(f"no URDF file at {path}")
        return path.stem, path.parent, {"urdf": path.name}
    if path.suffix == ".toml":
        if not path.is_file():
            raise RobotDescriptionError(f"no robot description at {path}")
        return path.parent.name, path.parent, _read_description(path)
    names = bundled_robots()
    if str(robot) not in names:
        raise RobotDescriptionError(
            f"unknown robot {str(robot)!r}; bundled robots: {', '.join(names)}; "
            "or give the path of a .urdf or robot.toml file"
        )
    folder = bundled_root() / str(robot)
    return str(robot), folder, _read_description(folder / "robot.toml")


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
    try:
        model = pin.buildModelFromUrdf(str(urdf_path))
    except (ValueError, RuntimeError) as error:
        first = str(error).splitlines()[0:3]
        raise RobotDescriptionError(f"{urdf_path}: not a valid URDF: {' '.join(first)}") from error
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
    return model, tree.getroot()


def _add_payload(model: pin.Model, frame: str, payload: float) -> None:
    """A point mass ``payload`` (kg) at the tool frame, carried by the tool's joint."""
    tool = model.frames[model.getFrameId(frame)]
    point_mass = pin.Inertia(payload, tool.placement.translation, np.zeros((3, 3)))
    model.inertias[tool.parentJoint] = model.inertias[tool.parentJoint] + point_mass


def load_robot(
    robot: str | Path, payload: float | None = None, task_axes: str | None = None
) -> Robot:
    """Load a bundled robot by name, or a robot from a ``robot.toml`` or ``.urdf`` path.

    A ``robot.toml`` names the URDF (``urdf``: a path beside it, or
    ``package://<distribution>/<path>``), the tool frame (``tool_frame``), the task axes
    (``task_axes``: world components of the tool position, e.g. "xz"), and optionally joints to
    lock at their neutral value (``locked_joints``), a default payload in kg (``payload``) and
    the robot's task file (``task``, see `redundancy.tasks`). A bare URDF takes its last link as
    the tool and the full position "xyz" as the task. ``payload`` (kg, ≥ 0) is a point mass at
    the tool frame, None taking the description's default, or 0; ``task_axes`` overrides the
    description's.
    """
    name, folder, description = _describe(robot)
    urdf_path = _urdf_path(folder, description["urdf"])
    model, root = _build_model(urdf_path, list(description.get("locked_joints", [])))
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    tool_frame = description.get("tool_frame", bodies[-1])
    if tool_frame not in bodies:
        raise RobotDescriptionError(
            f"tool frame {tool_frame!r} is not a link of {urdf_path.name}; links: {bodies}"
        )
    task_axes = task_axes or str(description.get("task_axes", AXES))
    if (
        not task_axes
        or any(a not in AXES for a in task_axes)
        or len(set(task_axes)) != len(task_axes)
    ):
        raise RobotDescriptionError(
            f"task_axes {task_axes!r} must be distinct letters among 'x', 'y', 'z'"
        )
    if payload is None:
        payload = float(description.get("payload", 0.0))
    if not np.isfinite(payload) or payload < 0:
        raise InvalidInputError(f"payload must be a finite mass ≥ 0 kg; got {payload}")
    if payload > 0:
        _add_payload(model, tool_frame, payload)
    actuators = ActuatorSet.bind(read_transmissions(root, urdf_path.name), model)
    task = description.get("task")
    task_file = None if task is None else folder / task
    return Robot(name, model, tool_frame, task_axes, actuators, payload, urdf_path, task_file)
