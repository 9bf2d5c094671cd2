"""The tool's angle as a task coordinate: y = (tool position on the task axes, φ), m = 3 on a
planar task.

φ is the angle about the task plane's normal n = e_a × e_b (a, b the robot's two task axes, in
their order) of a direction fixed in the tool, measured from axis a towards axis b: for
``task_axes = "xz"`` from world x towards world z, for "xy" from x towards y. It is read from
the one Pinocchio pass (`redundancy.model.kinematics`): a probe point one metre from the tool
frame's origin along one of the tool frame's axes is tracked beside the tool, and with
d = p_probe − p_tool,

    φ = atan2(d_b, d_a),   ∂φ/∂q = (d_a ∂d_b/∂q − d_b ∂d_a/∂q) / ρ²,   ρ² = d_a² + d_b²,

and its rate J̇_φ by the product rule on the tracked frames' J̇. The tool axis is the one of the
tool frame's x, y, z most nearly in the task plane at mid-range (on a planar arm one lies in it
at every configuration, and ρ = 1). The angle is measured on the branch (c − π, c + π] about a
centre c (default 0; a work cycle's `WorkCycle.angle_centre`), so that a task's angles never
wrap.

A robot that knows nothing of angles gains one with `with_tool_angle`: a `ToolAngleRobot` is the
same robot (same model, actuators, payload and hydraulics) whose task has the angle as its last
coordinate; everything else in the toolkit (laws, integration, inverse kinematics, searches,
bounds) reads its task through it and needs no change.
"""

from __future__ import annotations

import inspect
import math

import numpy as np
import pinocchio as pin

from redundancy.errors import InvalidInputError
from redundancy.model.kinematics import Kinematics, PointMotion
from redundancy.model.robot import AXES, Robot, frame_id, require_robot

PROBE = "tool_angle_probe"  # the tracked frame one metre along the tool's chosen axis


class ToolAngleRobot(Robot):
    """``base`` with the tool's angle about the task plane's normal as its last task coordinate
    (rad, on the branch about ``centre``); ``axis`` ("x", "y" or "z") the tool frame's axis whose
    direction is measured (default: the one most nearly in the plane at mid-range)."""

    tool_angle = True

    def __init__(self, base: Robot, centre: float = 0.0, axis: str | None = None) -> None:
        if len(base.task_axes) != 2:
            raise InvalidInputError(
                f"the tool's angle is a task coordinate on a planar task (two task axes); "
                f"{base.name}'s task is {base.task_axes!r}"
            )
        if isinstance(base, ToolAngleRobot):
            raise InvalidInputError(f"{base.name}'s task already has the tool's angle")
        model = pin.Model(base.model)  # a copy: the base robot keeps its own frames
        tool = frame_id(model, base.tool_frame)
        plane = [AXES.index(a) for a in base.task_axes]
        normal = np.cross(np.eye(3)[plane[0]], np.eye(3)[plane[1]])
        data = model.createData()
        middle = (base.lower + base.upper) / 2
        middle = np.where(np.isfinite(middle), middle, 0.0)
        pin.framesForwardKinematics(model, data, middle)
        rotation = data.oMf[tool].rotation
        if axis is None:
            column = int(np.argmin(np.abs(normal @ rotation)))
        elif axis in AXES:
            column = AXES.index(axis)
        else:
            raise InvalidInputError(f"tool axis {axis!r} must be one of x, y, z")
        if abs(normal @ rotation[:, column]) > 1 - 1e-6:
            raise InvalidInputError(
                f"the tool's {AXES[column]} axis is the task plane's normal; measure another"
            )
        frame = model.frames[tool]
        placement = frame.placement * pin.SE3(np.eye(3), np.eye(3)[column])
        model.addFrame(pin.Frame(PROBE, frame.parentJoint, tool, placement, pin.FrameType.OP_FRAME))
        given = list(inspect.signature(Robot.__init__).parameters)[1:]  # stored as themselves
        super().__init__(
            **{key: getattr(base, key) for key in given if key != "model"}, model=model
        )
        self.base = base
        self.centre = float(centre)
        self.tool_axis = AXES[column]
        self._plane = plane
        self._probe = frame_id(model, PROBE)
        self._task_frames.append(self._probe)

    def __repr__(self) -> str:
        return (
            f"ToolAngleRobot({self.name!r}, n={self.n}, m={self.m}: {self.task_axes} + angle, "
            f"payload={self.payload} kg)"
        )

    @property
    def m(self) -> int:
        return len(self.task_axes) + 1

    @property
    def task_labels(self) -> list[str]:
        """The task coordinates' names."""
        return [*self.task_axes, "angle"]

    def _angle(self, kinematics: Kinematics, rates: bool = True) -> tuple:
        """φ (k,), J_φ (k, n) and, with ``rates`` and velocities, φ̇ (k,) and J̇_φ (k, n) (else
        None)."""
        tool, probe = kinematics.point(self._tool), kinematics.point(self._probe)
        a, b = self._plane

        def cross(u: np.ndarray, U: np.ndarray) -> np.ndarray:
            """u_a U_b − u_b U_a, (k, n) for u (k, 3) and U (k, 3, n)."""
            return u[:, a, None] * U[:, b] - u[:, b, None] * U[:, a]

        d = probe.position - tool.position
        dJ = probe.jacobian - tool.jacobian
        rho2 = d[:, a] ** 2 + d[:, b] ** 2
        raw = np.arctan2(d[:, b], d[:, a])
        angle = self.centre + np.mod(raw - self.centre + math.pi, 2 * math.pi) - math.pi
        jacobian = cross(d, dJ) / rho2[:, None]
        if not rates or probe.velocity is None or tool.velocity is None:
            return angle, jacobian, None, None
        dd = probe.velocity - tool.velocity
        dJ_dot = probe.jacobian_rate - tool.jacobian_rate  # type: ignore[operator]
        rate = (d[:, a] * dd[:, b] - d[:, b] * dd[:, a]) / rho2
        spin = (d[:, a] * dd[:, a] + d[:, b] * dd[:, b]) / rho2  # ρ̇ / ρ
        jacobian_rate = (cross(dd, dJ) + cross(d, dJ_dot)) / rho2[:, None]
        jacobian_rate -= 2 * spin[:, None] * jacobian
        return angle, jacobian, rate, jacobian_rate

    def task_point(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        y, J = _stacked(super().task_point(kinematics), self._angle(kinematics, False))
        return y, J  # type: ignore[return-value]

    def task(self, kinematics: Kinematics) -> PointMotion:
        return PointMotion(*_stacked(super().task(kinematics), self._angle(kinematics)))


def _stacked(task: tuple, angle: tuple) -> list:
    """The task's arrays (k, m − 1, ...) with the angle's (k, ...) as their last row; None
    where either is None."""
    return [
        None if t is None or a is None else np.concatenate([t, a[:, None]], axis=1)
        for t, a in zip(task, angle)
    ]


def with_tool_angle(robot: Robot, centre: float = 0.0, axis: str | None = None) -> Robot:
    """``robot`` with the tool's angle as its last task coordinate (see the module docstring);
    one already measuring it is returned with its branch moved to ``centre``."""
    require_robot(robot)
    if isinstance(robot, ToolAngleRobot):
        return ToolAngleRobot(robot.base, centre, axis or robot.tool_axis)
    return ToolAngleRobot(robot, centre, axis)


def task_robot(robot: Robot, cycle) -> Robot:
    """The robot a work cycle's task is read on: with the tool's angle where the cycle asks for
    it (branch centred on the cycle's angles), else ``robot`` itself."""
    if getattr(cycle, "tool_angle", False):
        return with_tool_angle(robot, cycle.angle_centre)
    return robot


def task_labels(robot: Robot) -> list[str]:
    """The names of ``robot``'s task coordinates: its task axes, and "angle" where it has one."""
    return list(getattr(robot, "task_labels", list(robot.task_axes)))
