"""`Robot`: a Pinocchio model with its tool point, task axes, actuators and joint limits.

Every joint-space quantity comes from Pinocchio's C++ algorithms, looped over a batch in the
compiled core (`redundancy._core.Pass`): the tracked frames' kinematics
(`redundancy.model.kinematics`), the mass matrix M(q) (CRBA), the nonlinear terms
N(q, v) = V(q, v) + G(q) (RNEA). The core holds its own copy of the model, read from
Pinocchio's serialization of ``Robot.model`` at the first pass. Robots are built by
`redundancy.model.loading.load_robot`.

Configurations come one at a time, shape (n,), or as a batch, shape (k, n); `configuration`
checks them into a batch, the batch axis first, which every method then takes.
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path

import numpy as np
import pinocchio as pin

from redundancy._core import Evaluator, HeldPass, Pass
from redundancy.errors import InvalidInputError
from redundancy.model.actuators import ActuatorSet, CompiledMap, declared, driven_joints, prismatic
from redundancy.model.hydraulics import Circuit
from redundancy.model.kinematics import Kinematics, PointMotion, Tracking, track
from redundancy.model.values import modulo_turn

AXES = "xyz"
SINGULAR_TOLERANCE = 1e-9  # A counts as singular below σ_min / σ_max = 1e-9


def frame_id(model: pin.Model, name: str) -> int:
    """The frame of the link ``name``, or of the point of that name added to the model (an
    actuator's attachment, the tool point): never a joint's frame, which a URDF may give the
    same name as a link."""
    for kind in (pin.FrameType.BODY, pin.FrameType.OP_FRAME):
        if model.existFrame(name, kind):
            return model.getFrameId(name, kind)
    raise InvalidInputError(f"no link or point {name!r} in the model")


def _as_batch(name: str, values: np.ndarray | list[float], n: int) -> np.ndarray:
    """``values`` (n,) or (k, n) as a checked (k, n) float array: real, right shape, finite."""
    try:
        if np.iscomplexobj(values):  # numpy would drop the imaginary part with a warning
            raise TypeError
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"{name} must be {n} numbers, or k rows of {n}; got {values!r}"
        ) from None
    if array.ndim not in (1, 2) or array.shape[-1] != n:
        raise InvalidInputError(f"{name} must have shape ({n},) or (k, {n}); got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f"{name} contains NaN or infinite values: {array.tolist()}")
    return np.atleast_2d(array)


def require_robot(robot: object) -> None:
    """Refuse, in one line, what a function taking a `Robot` first was given instead (a bundled
    robot's name, most often)."""
    if not isinstance(robot, Robot):
        raise InvalidInputError(
            f"robot must be a Robot, as load_robot(name) gives one; got {robot!r}"
        )


class Robot:
    """A manipulator: Pinocchio model, tool point, task axes, actuators and limits, and its
    hydraulic circuit where one is declared (`redundancy.model.hydraulics`).

    The task y is the tool position's world components ``task_axes`` (m of them); n joints; one
    actuator per joint (``actuators``), so that A = ∂x/∂q is square. ``description`` is the
    URDF text the model was built from (a xacro expanded, meshes by absolute path),
    ``missing_meshes`` the mesh references no file answers, and ``zero_masses`` the links whose
    ``<inertial>`` gives a mass of 0 (a massless link not among them has no ``<inertial>``).
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
        hydraulics: Circuit | None = None,
        description: str = "",
        missing_meshes: tuple[str, ...] = (),
        zero_masses: tuple[str, ...] = (),
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
        self.hydraulics = hydraulics
        self.description = description
        self.missing_meshes = missing_meshes
        self.zero_masses = zero_masses
        self._tool = frame_id(model, tool_frame)
        self._task_rows = [AXES.index(a) for a in task_axes]
        self._task_frames = [self._tool]  # the frames the task is read from
        self._tracking: dict[tuple[int, ...], Tracking] = {}
        self._evaluators: dict[ActuatorSet, Evaluator | None] = {}
        self._held_passes: dict[ActuatorSet, HeldPass | None] = {}

    def __getstate__(self) -> dict:
        """What a copy sent to a worker process is rebuilt from: none of its compiled passes
        and evaluators, which are built there again when first asked for (and which pickle
        protocols 0 and 1 cannot rebuild: the interpreter aborted)."""
        state = {**vars(self), "_tracking": {}, "_evaluators": {}, "_held_passes": {}}
        state.pop("_dynamics", None)
        return state

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, n={self.n}, m={self.m}, payload={self.payload} kg)"

    def circuit(self) -> Circuit:
        """The robot's hydraulics, or `InvalidInputError` saying how to declare them."""
        if self.hydraulics is None:
            raise InvalidInputError(
                f"{self.name} has no hydraulics; declare a [hydraulics] table in its robot.toml "
                "or give one with --hydraulics FILE (schema in docs/hydraulics.md)"
            )
        return self.hydraulics

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
        """The joints with a degree of freedom, in the order of q (mimic joints follow them)."""
        return driven_joints(self.model)

    @cached_property
    def rotary_joints(self) -> np.ndarray:
        """Which joints are angles (rad) rather than lengths (m), (n,) bool."""
        return np.array([not prismatic(self.model, name) for name in self.joint_names])

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits (n,), rad or m."""
        return self.model.lowerPositionLimit

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits (n,), rad or m."""
        return self.model.upperPositionLimit

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        """A finite box of joint values, lower and upper (n,) each: the joint limits, and of an
        angle whose range is wider than a turn (unbounded, or a URDF's ±1e16 for "no limit"),
        the turn within it nearest [−π, π]: every pose once. Searches seed configurations in
        it."""
        lower, upper, wide = self.lower, self.upper, self.turning
        turn = np.where(wide, np.minimum(np.maximum(lower, -np.pi), upper - 2 * np.pi), lower)
        return turn, np.where(wide, turn + 2 * np.pi, upper)

    @property
    def turning(self) -> np.ndarray:
        """Which joints are angles whose range is wider than a turn (n,) bool: a continuous
        joint's among them, whose values a whole turn apart are one pose."""
        return self.rotary_joints & (self.upper - self.lower > 2 * np.pi)

    @cached_property
    def actuator_turns(self) -> np.ndarray:
        """How much each actuator's stroke changes where its joint turns once, the others held
        (n,), rad or m: 2π for a slew driven directly, 2π × its ratio through a gear (a kind of
        your own), and 0 where the stroke comes back to itself (a cylinder) or the joint does
        not turn (`turning`). Read by the actuators' own evaluation, at the middle of `span`
        and a turn beyond it; a change below 1e-9 of the stroke is rounding."""
        turns = np.zeros(self.n)
        joints = np.array([a.index for a in self.actuators.maps])
        rows = np.flatnonzero(self.turning[joints])
        if len(rows):
            lower, upper = self.span
            q = np.repeat(((lower + upper) / 2)[None], 1 + len(rows), axis=0)
            q[1 + np.arange(len(rows)), joints[rows]] += 2 * np.pi
            x, _ = self.actuators.evaluate(self.kinematics(q))
            change = x[1 + np.arange(len(rows)), rows] - x[0, rows]
            turns[rows] = np.where(np.abs(change) > 1e-9 * (1 + np.abs(x[0, rows])), change, 0)
        return turns

    def turned(self, change: np.ndarray) -> np.ndarray:
        """Changes of the strokes (..., n), of an actuator with no stroke end that its joint
        turns (`actuator_turns`: T ≠ 0) within [−|T|/2, |T|/2), a whole number of turns from
        the change: turning it once round leaves the machine as it was and winds nothing up (a
        stroke with ends counts every turn)."""
        turn = np.abs(self.actuator_turns)
        endless = ~(np.isfinite(self.actuators.lower) | np.isfinite(self.actuators.upper))
        free = (turn > 0) & endless
        change = np.array(change, dtype=float)
        change[..., free] = np.remainder(change[..., free] + turn[free] / 2, turn[free])
        change[..., free] -= turn[free] / 2
        return change

    def nearest_turn(self, values: np.ndarray, to: np.ndarray) -> np.ndarray:
        """The strokes ``values`` (n,), each of an actuator that its joint turns
        (`actuator_turns`) with a stroke wider than its turn moved by the whole turns that
        bring it nearest ``to`` (n,) inside its stroke: where a self-motion from ``to`` to
        that pose goes the short way."""
        turn, lower, upper = np.abs(self.actuator_turns), self.actuators.lower, self.actuators.upper
        turns = (turn > 0) & (upper - lower > turn)
        step = np.where(turns, turn, 1.0)
        whole = np.round((to - values) / step)
        candidates = values + step * (whole + np.array([[-1.0], [0.0], [1.0]]))
        candidates = np.concatenate([candidates, [values]])  # values itself is always inside
        inside = (candidates >= lower) & (candidates <= upper)
        nearest = np.argmin(np.where(inside, np.abs(candidates - to), np.inf), axis=0)
        moved = candidates[nearest, np.arange(len(values))]
        return np.where(turns, moved, values)

    def same_poses(self, q: np.ndarray, other: np.ndarray, tolerance: float) -> np.ndarray:
        """Whether configurations ``q`` and ``other`` (..., n), broadcast against each other,
        are one pose to ``tolerance``: each joint within it, a `turning` one modulo a turn."""
        apart = np.asarray(q, dtype=float) - np.asarray(other, dtype=float)
        apart = np.where(self.turning, modulo_turn(apart), apart)
        return np.all(np.abs(apart) <= tolerance, axis=-1)

    def same_pose(self, q: np.ndarray, other: np.ndarray, tolerance: float) -> bool:
        """`same_poses` of two configurations (n,)."""
        return bool(self.same_poses(q, other, tolerance))

    def configuration(self, q: np.ndarray | list[float], name: str = "q") -> np.ndarray:
        """``q`` as a checked (k, n) array: right shape, finite."""
        return _as_batch(name, q, self.n)

    def task_values(self, y: np.ndarray | list[float], name: str = "y_dot") -> np.ndarray:
        """Task coordinates or velocities ``y`` as a checked (k, m) array: right shape, finite."""
        return _as_batch(name, y, self.m)

    def kinematics(
        self, q: np.ndarray, v: np.ndarray | None = None, actuators: ActuatorSet | None = None
    ) -> Kinematics:
        """Pinocchio's kinematics at the states (q, v), each (k, n), of the frames the task and
        ``actuators`` (default: all the robot's; a `ActuatorSet.part` for fewer) are read from:
        the fewer the frames, the cheaper the pass."""
        return track(self.tracking(actuators), q, v)

    def tracking(self, actuators: ActuatorSet | None = None) -> Tracking:
        """The compiled pass over the frames the task and ``actuators`` (default: all the
        robot's) are read from, built once per set of frames."""
        key = (self.actuators if actuators is None else actuators).frames
        if key not in self._tracking:
            frames = list(dict.fromkeys([*self._task_frames, *key]))
            slots = {f: i for i, f in enumerate(frames)}
            self._tracking[key] = Tracking(Pass(self._serialized, frames), frames, slots)
        return self._tracking[key]

    def evaluator(self) -> Evaluator | None:
        """The compiled evaluation of states in actuator coordinates
        (`redundancy.resolution.state.evaluate`), built once per set of actuators; None where
        an actuator is a kind of your own or the task is not the tool's position (`task_point`
        overridden): Python then evaluates them."""
        return self._compiled(self._evaluators, self.actuators, Evaluator, SINGULAR_TOLERANCE)

    def held_pass(self, part: ActuatorSet) -> HeldPass | None:
        """The compiled pass that reads the task point and the actuators ``part`` alone, y, J,
        x and A (inverse kinematics, `redundancy.planning.ik.newton`), built once per part; None
        where one is a kind of your own or the task is not the tool's position."""
        return self._compiled(self._held_passes, part, HeldPass)

    def _compiled(self, built: dict, part: ActuatorSet, kind: type, *more):
        """The core's ``kind`` over the tool point and ``part`` (and ``more`` arguments), kept
        in ``built``; None where the core cannot read them."""
        if part not in built:
            maps, tracking = list(part), self.tracking(part)
            own = type(self).task_point is not Robot.task_point
            built[part] = (
                None
                if own or not all(isinstance(m, CompiledMap) for m in maps)
                else kind(
                    tracking.core,
                    tracking.slots[self._tool],
                    self._task_rows,
                    *declared(maps, tracking.slots),  # type: ignore[arg-type]
                    *more,
                )
            )
        return built[part]

    @property
    def task_rows(self) -> tuple[int, list[int]]:
        """The tool point's frame and which of its world components (0, 1, 2 for x, y, z) the
        task y is."""
        return self._tool, self._task_rows

    @cached_property
    def _serialized(self) -> str:
        """The model in Pinocchio's serialization: what the compiled passes are built from."""
        return self.model.saveToString()

    @cached_property
    def _dynamics(self) -> Pass:
        """The compiled pass that tracks no frame: M(q) and N(q, v)."""
        return Pass(self._serialized, [])

    def tool(self, kinematics: Kinematics) -> PointMotion:
        """Motion of the tool point, all three world components."""
        return kinematics.point(self._tool)

    def task_point(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Task coordinates y (k, m) and task Jacobian J = ∂y/∂q (k, m, n) (Eqs. 6-7)."""
        slot, rows = kinematics.slots[self._tool], self._task_rows
        return kinematics.positions[:, slot, rows], kinematics.jacobians[:, slot, rows]

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

    @property
    def kinematic_only(self) -> bool:
        """Whether some links have no mass (`massless_links`), so that M(q) is undefined."""
        return bool(self.massless_links)

    @property
    def massless(self) -> str:
        """The massless links in words, as the URDF has them: without ``<inertial>``, or with a
        zero ``<mass>``."""
        without = [link for link in self.massless_links if link not in self.zero_masses]
        zero = [link for link in self.massless_links if link in self.zero_masses]
        said = [
            f"links {', '.join(links)} {what}"
            for links, what in ((without, "have no <inertial>"), (zero, "have a zero <mass>"))
            if links
        ]
        return f"{' and '.join(said)} in {self.urdf.name}"

    def require_masses(self, what: str) -> None:
        """Refuse ``what`` (e.g. "M(q)") on a kinematic-only robot, naming its massless links."""
        if self.kinematic_only:
            # a circuit's load pressures need the forces, and a study reports them
            circuit = "" if self.hydraulics is None else " without its [hydraulics] table"
            raise InvalidInputError(
                f"{self.name} is kinematic only: {self.massless}, and {what} needs masses; give "
                "them <inertial> elements with a mass > 0, or use what needs none (the velocity "
                f"objective{circuit}, play, check)"
            )

    def mass_matrices(self, q: np.ndarray) -> np.ndarray:
        """M(q) (k, n, n) for configurations q (k, n) already checked (`configuration`)."""
        self.require_masses("M(q) and the dynamics (M_H, N_H, F_H, the energy objective)")
        out, state = self._dynamics.mass_matrices(q)
        if state >= 0 and not np.isfinite(out[state]).all():
            raise InvalidInputError(
                f"{self.name}: M(q) is not finite at q = {self.written(q[state])}: its numbers "
                f"overflow there (the joints' limits: {self.written(self.lower)} to "
                f"{self.written(self.upper)})"
            )
        if state >= 0:  # a massless link is refused above
            joints = [self.joint_names[j] for j in np.flatnonzero(np.diagonal(out[state]) <= 0)]
            raise InvalidInputError(
                f"{self.name}: M(q) is singular at q = {self.written(q[state])}"
                f": nothing beyond joints {joints} has mass off their axes or inertia about them, "
                "so the dynamics (M_H, N_H, F_H, the energy objective) are undefined there; give "
                f"those links' <inertial> in {self.urdf.name} inertia about the joints' axes"
            )
        return out

    @staticmethod
    def written(values: np.ndarray) -> str:
        """Joint or actuator values as a message writes them: [v, …] to 4 significant digits."""
        return f"[{', '.join(f'{v:.4g}' for v in values)}]"

    @cached_property
    def massless_links(self) -> list[str]:
        """The links (bodies) of zero mass."""
        return [
            frame.name
            for frame in self.model.frames
            if frame.type == pin.FrameType.BODY
            and frame.parentJoint > 0
            and self.model.inertias[frame.parentJoint].mass == 0
        ]

    def nonlinear(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """N(q, v) = V(q, v) + G(q) (Eq. 20), (k, n) in N·m or N, for states q, v (k, n) already
        checked (`configuration`)."""
        self.require_masses("N(q, v)")
        return self._dynamics.nonlinear(q, v)

    def skeleton(self, q: np.ndarray) -> np.ndarray:
        """The machine as rods at the states q (k, n): (k, R, 2, 3) ends in m, world frame, of
        a rod from each joint's parent joint's origin (or the world's) to its own, and one from
        the tool's joint to the tool point. What a figure or a playback draws of the links,
        whose poses the one pass does not track."""
        model, data = self.model, self.data
        pairs = [(int(model.parents[j]), j) for j in range(1, model.njoints)]
        tool_joint = model.frames[self._tool].parentJoint
        rods = []
        for row in q:
            pin.forwardKinematics(model, data, row)
            origins = [placement.translation.copy() for placement in data.oMi]
            tool = pin.updateFramePlacement(model, data, self._tool).translation
            rods.append(
                [(origins[a], origins[b]) for a, b in pairs] + [(origins[tool_joint], tool)]
            )
        return np.array(rods)
