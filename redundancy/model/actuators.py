"""Actuator maps: joint space → hydraulic coordinates, x = h2(q) (Eq. 9), A = ∂x/∂q (Eq. 11).

Each actuator coordinate x_i is one `ActuatorMap`; a kind of your own is a subclass, found by
class name (no registry). Maps are declarations (names of joints and links); `ActuatorSet.bind`
resolves copies of them against a Pinocchio model, so one declaration serves several robots.
"""

from __future__ import annotations

import copy
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from redundancy import _core
from redundancy.errors import (
    InvalidInputError,
    RobotDescriptionError,
    SingularConfigurationError,
    placed,
    prefixed,
)
from redundancy.model.kinematics import Kinematics
from redundancy.model.parameters import Number, Parameter, Point


def driven_joints(model: pin.Model) -> list[str]:
    """The joints of ``model`` with a degree of freedom, in order; mimic joints, which follow
    another joint, are not among them."""
    return [name for name, joint in zip(model.names[1:], model.joints[1:]) if joint.nv > 0]


class ActuatorMap(ABC):
    """One actuator coordinate x_i(q) with its stroke limits [lower, upper] (m or rad).

    ``joint`` names the joint it drives; ``rotary``: x_i is an angle (rad), not a length (m).
    A kind lists its parameters once, in ``parameters`` (`redundancy.model.parameters`), each a
    keyword of its constructor and an attribute of its instances; that list reads both an
    ``[actuators.<name>]`` table of ``robot.toml`` and a URDF ``<transmission>``. A kind of your
    own::

        class GearedMotor(ActuatorMap):
            parameters = (Number("ratio", "motor turns per joint turn"),)

            def __init__(self, name, joint, lower=-np.inf, upper=np.inf, ratio=1.0):
                super().__init__(name, joint, lower, upper)
                self.ratio = ratio

            def evaluate(self, kinematics): ...
            def rate(self, kinematics): ...

    is declared as ``[actuators.slew] kind = "GearedMotor", joint = "...", ratio = 50`` or as
    ``<transmission name="slew"><type>redundancy/GearedMotor</type>...<ratio value="50"/>``.
    """

    rotary = False
    distance = False  # whether x is a distance between two points (m, ≥ 0), a cylinder's length
    parameters: tuple[Parameter, ...] = ()
    declared_in = ""  # the file and table that declare it, for messages; "" for a default

    @property
    def unit(self) -> str:
        """The SI unit of its stroke x: rad for a rotary actuator, else m."""
        return "rad" if self.rotary else "m"

    def __init__(self, name: str, joint: str, lower: float = -np.inf, upper: float = np.inf):
        if not lower < upper:
            raise RobotDescriptionError(
                f"actuator {name!r}: stroke lower {lower} must be below upper {upper}"
            )
        self.name = name
        self.joint = joint
        self.lower = float(lower)
        self.upper = float(upper)
        self.index = -1  # velocity index of ``joint``, set by bind
        self.frames: list[int] = []  # Pinocchio frames whose motion evaluate() reads

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}({self.name!r}, joint={self.joint!r}, "
            f"stroke=[{self.lower:g}, {self.upper:g}])"
        )

    @classmethod
    def kinds(cls) -> dict[str, type[ActuatorMap]]:
        """Every concrete kind defined so far, including users' subclasses, by class name."""
        found: dict[str, type[ActuatorMap]] = {}
        for kind in cls.__subclasses__():
            if not getattr(kind, "__abstractmethods__", None):
                found[kind.__name__] = kind
            found |= kind.kinds()
        return found

    def bind(self, model: pin.Model) -> None:
        """Resolve names against ``model``; raise `RobotDescriptionError` naming the valid ones."""
        joints = driven_joints(model)
        if self.joint in model.names and self.joint not in joints:
            raise RobotDescriptionError(
                f"actuator {self.name!r} drives joint {self.joint!r}, which mimics another "
                f"joint; declare the actuator on the joint it follows; joints: {', '.join(joints)}"
            )
        if model.existFrame(self.joint, pin.FrameType.FIXED_JOINT):
            raise RobotDescriptionError(
                f"actuator {self.name!r} drives joint {self.joint!r}, which is fixed (or locked); "
                f"an actuator drives a joint that moves; joints: {', '.join(joints)}"
            )
        if self.joint not in joints:
            raise RobotDescriptionError(
                f"actuator {self.name!r} drives joint {self.joint!r}, which does not exist; "
                f"joints: {', '.join(joints)}"
            )
        self.index = model.joints[model.getJointId(self.joint)].idx_v

    @abstractmethod
    def evaluate(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """x_i (k,) and its row of A, ∂x_i/∂q (k, n), at a batch of states."""

    @abstractmethod
    def rate(self, kinematics: Kinematics) -> np.ndarray:
        """The row of Ȧ = dA/dt (k, n); ``kinematics`` carries velocities."""

    @classmethod
    def evaluate_group(
        cls, maps: list[ActuatorMap], kinematics: Kinematics
    ) -> tuple[np.ndarray, np.ndarray]:
        """x (k, c) and rows of A (k, c, n) of c maps of this kind; kinds may vectorise it."""
        parts = [m.evaluate(kinematics) for m in maps]
        return np.stack([p[0] for p in parts], axis=1), np.stack([p[1] for p in parts], axis=1)

    @classmethod
    def rate_group(cls, maps: list[ActuatorMap], kinematics: Kinematics) -> np.ndarray:
        """Rows of Ȧ (k, c, n) of c maps of this kind; kinds may vectorise it."""
        return np.stack([m.rate(kinematics) for m in maps], axis=1)

    def declared(self) -> dict[str, object]:
        """The values of the kind's `parameters`, by name."""
        return {parameter.name: getattr(self, parameter.name) for parameter in self.parameters}


def prismatic(model: pin.Model, joint: str) -> bool:
    """Whether ``joint`` of ``model`` is prismatic (its coordinate a length, m)."""
    kind = model.joints[model.getJointId(joint)].shortname()
    return "Prismatic" in kind or kind.startswith("JointModelP")


def attach_frame(
    model: pin.Model, name: str, link: str, point: np.ndarray, refused: Callable[[str], str]
) -> int:
    """Add to ``model`` a frame ``name`` at ``point`` (3,) m in ``link``'s frame, or move it there
    if the model has it already (an actuator bound again, e.g. redesigned), and return its id;
    where ``link`` is none, `RobotDescriptionError` ``refused(links)``, given the links."""
    links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    if link not in links:
        raise RobotDescriptionError(refused(", ".join(links)))
    parent_id = model.getFrameId(link, pin.FrameType.BODY)
    parent = model.frames[parent_id]
    placement = parent.placement * pin.SE3(np.eye(3), np.asarray(point, dtype=float))
    frame = pin.Frame(name, parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME)
    if model.existFrame(frame.name, pin.FrameType.OP_FRAME):  # bound before: the point moves
        frame_id = model.getFrameId(frame.name, pin.FrameType.OP_FRAME)  # to where it is declared
        model.frames[frame_id] = frame
        return frame_id
    return model.addFrame(frame, False)


class CompiledMap(ActuatorMap):
    """A built-in kind, computed by the compiled core (`redundancy._core.actuate`, the one
    implementation its batches and the control step share): it says which of the core's kinds
    it is (``code``) and what the core reads of it (`declare`). The single-map methods follow
    from the group methods, which evaluate every compiled map of a set in one call."""

    code: int  # the core's kind: 0 a joint driven directly, 1 a cylinder, 2 a linkage

    @abstractmethod
    def declare(self, slots: dict[int, int]) -> tuple[list[int], list[float]]:
        """The slots among the tracked frames (``slots``: frame id → slot) the core reads, and
        the numbers it needs; for each kind, see `redundancy._core`'s `Actuator`."""

    def attach(self, model: pin.Model, end: str, link: str, point: np.ndarray) -> int:
        """`attach_frame` of the frame ``<name>/<end>``."""

        def refused(links: str) -> str:
            exists = f"actuator {self.name!r} is attached to link {link!r}, which does not exist"
            return f"{exists}; links: {links}"

        return attach_frame(model, f"{self.name}/{end}", link, point, refused)

    def evaluate(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        x, rows = self.evaluate_group([self], kinematics)
        return x[:, 0], rows[:, 0]

    def rate(self, kinematics: Kinematics) -> np.ndarray:
        return self.rate_group([self], kinematics)[:, 0]

    @classmethod
    def evaluate_group(cls, maps, kinematics):
        return actuate(maps, kinematics)[:2]

    @classmethod
    def rate_group(cls, maps, kinematics):
        return actuate(maps, kinematics, moving=True)[2]

    def refuse(self, kinematics: Kinematics, state: int, status: int) -> None:
        """Raise `SingularConfigurationError` for what the core could not do at ``state``: the
        base's, a cylinder of zero length."""
        q = np.round(kinematics.q[state], 6).tolist()
        raise SingularConfigurationError(
            f"cylinder {self.name!r} has zero length at q = {q}: its attachment points coincide"
        )


def declared(maps: list[CompiledMap], slots: dict[int, int]) -> tuple[np.ndarray, ...]:
    """The compiled ``maps`` as the core reads them: kinds (c,), slots (c, 4), numbers (c, 3)."""
    kinds, frames, numbers = np.empty(len(maps), np.intc), np.zeros((len(maps), 4), np.intp), []
    for row, m in enumerate(maps):
        read, values = m.declare(slots)
        kinds[row], frames[row, : len(read)] = m.code, read
        numbers.append([*values, *[0.0] * (3 - len(values))])
    return kinds, frames, np.array(numbers, dtype=float).reshape(len(maps), 3)


def actuate(
    maps: list[CompiledMap], kinematics: Kinematics, moving: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """x (k, c), rows of A (k, c, n), if ``moving`` rows of Ȧ (k, c, n) (else None) and where
    each rod ends (k, c, 3), world, m, of c compiled ``maps``, by the core; what it cannot
    evaluate raises (`CompiledMap.refuse`)."""
    rates = (kinematics.v, kinematics.velocities, kinematics.jacobian_rates) if moving else ()
    known, key = kinematics.tracking.declared, tuple(maps)
    if key not in known:
        known[key] = declared(maps, kinematics.slots)
    x, rows, rate_rows, ends, status = _core.actuate(
        *known[key],
        kinematics.q,
        kinematics.positions,
        kinematics.jacobians,
        *rates,
    )
    if status.any():
        state, column = np.argwhere(status)[0]
        maps[column].refuse(kinematics, state, status[state, column])
    return x, rows, rate_rows, ends


class Identity(CompiledMap):
    """An electric or directly driven joint: x_i = q_j + offset, A row = e_j, Ȧ row = 0.

    Rotary (rad) on a revolute joint, a length (m) on a prismatic one.
    """

    code = 0
    offset = 0.0

    def bind(self, model: pin.Model) -> None:
        super().bind(model)
        self.rotary = not prismatic(model, self.joint)

    def declare(self, slots):
        return [], [self.index, self.offset]


class Prismatic(Identity):
    """A prismatic joint driven directly by a cylinder: x_i = q_j + offset.

    The crane's telescope: x3 = d3 − L2 + L3 (Eq. 9), offset = L3 − L2.
    """

    parameters = (Number("offset", "x − q, m", 0.0),)

    def __init__(
        self, name: str, joint: str, lower: float = -np.inf, upper: float = np.inf, offset=0.0
    ):
        super().__init__(name, joint, lower, upper)
        self.offset = float(offset)

    def bind(self, model: pin.Model) -> None:
        super().bind(model)
        if self.rotary:
            kind = model.joints[model.getJointId(self.joint)].shortname()
            raise RobotDescriptionError(
                f"actuator {self.name!r}: joint {self.joint!r} is {kind}, not prismatic; "
                "use Identity or LinearCylinder for a revolute joint"
            )


class LinearCylinder(CompiledMap):
    """A cylinder between a point on one link and a point on another: x_i = |p_rod − p_base|.

    A row = uᵀ (J_rod − J_base), u = (p_rod − p_base)/x_i; its rate
    Ȧ row = u̇ᵀ (J_rod − J_base) + uᵀ (J̇_rod − J̇_base), u̇ = (I − u uᵀ)(ṗ_rod − ṗ_base)/x_i.
    For the crane this is Eq. (9), x_i = √(L_i1² + L_i2² − 2 L_i1 L_i2 cos q_i), with the torque
    arm a_i = L_i1 L_i2 sin q_i / x_i (Eq. 14) on the diagonal of A. Points are (3,) in m, given
    in the link frames.
    """

    code = 1
    distance = True
    parameters = (
        Point("base", "the cylinder's base point", tag="attachment"),
        Point("rod", "the cylinder's rod point", tag="attachment"),
    )

    def __init__(
        self,
        name: str,
        joint: str,
        lower: float,
        upper: float,
        base: tuple[str, np.ndarray | list[float]],
        rod: tuple[str, np.ndarray | list[float]],
    ):
        super().__init__(name, joint, lower, upper)
        self.base = (base[0], np.asarray(base[1], dtype=float))
        self.rod = (rod[0], np.asarray(rod[1], dtype=float))

    def bind(self, model: pin.Model) -> None:
        """Resolve the links and add a Pinocchio frame at each attachment point (a frame this
        actuator added to ``model`` before is moved to the point now declared)."""
        super().bind(model)
        self.frames = [self.attach(model, "base", *self.base), self.attach(model, "rod", *self.rod)]

    def declare(self, slots):
        return [slots[f] for f in self.frames], []

    def ends(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """The base and rod points (k, 3), world, in m."""
        base, rod = (kinematics.point(f).position for f in self.frames)
        return base, rod


class ActuatorSet:
    """The robot's actuators, one per joint, ordered like the joints: x (k, n), A (k, n, n)."""

    source = ""  # the robot's description (robot.toml, or a bare URDF), where they are declared

    def __init__(self, maps: list[ActuatorMap]):
        """``maps`` bound to the robot's model (`bind`)."""
        self.maps = maps
        self.frames = tuple(dict.fromkeys(f for a in maps for f in a.frames))
        """The Pinocchio frames the actuators are evaluated from, in order, each once."""
        self._grouped = self._groups()
        self._parts: dict[tuple[int, ...], ActuatorSet] = {}

    @classmethod
    def bind(cls, maps: list[ActuatorMap], model: pin.Model) -> ActuatorSet:
        """Bound copies of ``maps``, one per joint of ``model``.

        Joints no map drives get an `Identity` actuator named after the joint, with the joint
        limits as stroke, and a warning names them.
        """
        joints = driven_joints(model)
        bound: dict[str, ActuatorMap] = {}
        for declared in maps:
            actuator = copy.copy(declared)
            with prefixed(actuator.declared_in):  # named where the actuator is declared
                actuator.bind(model)
            if actuator.joint in bound:
                first = bound[actuator.joint]
                raise RobotDescriptionError(
                    placed(
                        actuator.declared_in,
                        f"joint {actuator.joint!r} is driven twice: by {first.name!r}"
                        f"{f' ({first.declared_in})' if first.declared_in else ''} and "
                        f"{actuator.name!r}; each joint takes one actuator",
                    )
                )
            bound[actuator.joint] = actuator
        names = [a.name for a in bound.values()]
        if len(set(names)) != len(names):
            raise RobotDescriptionError(f"actuator names must be distinct; got {names}")
        undriven = [j for j in joints if j not in bound]
        named = {a.name: a for a in bound.values()}
        if clash := next((j for j in undriven if j in named), None):
            actuator = named[clash]
            raise RobotDescriptionError(
                placed(
                    actuator.declared_in,
                    f"actuator {clash!r} drives joint {actuator.joint!r} and is named like joint "
                    f"{clash!r}, which no actuator drives: its direct drive takes the joint's "
                    f"name; rename the actuator, or declare one on joint {clash!r}",
                )
            )
        if undriven:
            warnings.warn(
                f"joints without an actuator declaration are driven directly (Identity): "
                f"{', '.join(undriven)}",
                stacklevel=3,
            )
        for joint in undriven:
            j = model.joints[model.getJointId(joint)].idx_q
            actuator = Identity(
                joint, joint, model.lowerPositionLimit[j], model.upperPositionLimit[j]
            )
            actuator.bind(model)
            bound[joint] = actuator
        return cls(sorted(bound.values(), key=lambda a: a.index))

    def __len__(self) -> int:
        return len(self.maps)

    def __iter__(self):
        return iter(self.maps)

    def __getitem__(self, name: str) -> ActuatorMap:
        for actuator in self.maps:
            if actuator.name == name:
                return actuator
        raise KeyError(f"no actuator {name!r}; actuators: {', '.join(self.names)}")

    @property
    def names(self) -> list[str]:
        return [a.name for a in self.maps]

    def rows(self, chosen: str | Sequence[str]) -> list[int]:
        """The rows of the actuators ``chosen`` (one name, or several), in that order;
        `InvalidInputError` names any that is not an actuator's name."""
        names = self.names
        given = [chosen] if isinstance(chosen, str) else chosen
        if not isinstance(given, list | tuple) or not all(isinstance(c, str) for c in given):
            raise InvalidInputError(
                f"actuators must be given by name, e.g. {names[-1]!r}; got {chosen!r}"
            )
        unknown = sorted({c for c in given if c not in names})
        if unknown:
            raise InvalidInputError(f"unknown actuators {unknown}; actuators: {', '.join(names)}")
        return [names.index(c) for c in given]

    def part(self, rows: list[int]) -> ActuatorSet:
        """The actuators at ``rows``, in that order, as a set of their own (kept, so that its
        frames are looked up once): what evaluates only the actuators a computation reads."""
        key = tuple(rows)
        if key not in self._parts:
            self._parts[key] = ActuatorSet([self.maps[r] for r in rows])
        return self._parts[key]

    @property
    def lower(self) -> np.ndarray:
        """Lower stroke limits (n,)."""
        return np.array([a.lower for a in self.maps])

    @property
    def upper(self) -> np.ndarray:
        """Upper stroke limits (n,)."""
        return np.array([a.upper for a in self.maps])

    @property
    def rotary(self) -> np.ndarray:
        """Which actuators are angles (rad) rather than lengths (m), (n,) bool."""
        return np.array([a.rotary for a in self.maps])

    def _groups(self) -> list[tuple[type[ActuatorMap], list[ActuatorMap], slice | np.ndarray]]:
        """The maps by kind, with their rows (a slice where they are consecutive):
        [(kind, maps, rows)]."""
        kinds: dict[type[ActuatorMap], list[int]] = {}
        for row, actuator in enumerate(self.maps):  # the compiled kinds in one call
            kind = CompiledMap if isinstance(actuator, CompiledMap) else type(actuator)
            kinds.setdefault(kind, []).append(row)
        groups = []
        for kind, rows in kinds.items():
            consecutive = rows == list(range(rows[0], rows[-1] + 1))
            chosen = slice(rows[0], rows[-1] + 1) if consecutive else np.array(rows)
            groups.append((kind, [self.maps[r] for r in rows], chosen))
        return groups

    def evaluate(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """x = h2(q) (k, n) and A = ∂x/∂q (k, n, n) (Eqs. 10-11)."""
        k, n = kinematics.q.shape
        x, A = np.empty((k, len(self.maps))), np.empty((k, len(self.maps), n))
        for kind, maps, rows in self._grouped:
            x[:, rows], A[:, rows] = kind.evaluate_group(maps, kinematics)
        return x, A

    def rate(self, kinematics: Kinematics) -> np.ndarray:
        """Ȧ (k, n, n), so that ẍ = A q̈ + Ȧ q̇ (Eq. 12)."""
        k, n = kinematics.q.shape
        A_dot = np.empty((k, len(self.maps), n))
        for kind, maps, rows in self._grouped:
            A_dot[:, rows] = kind.rate_group(maps, kinematics)
        return A_dot
