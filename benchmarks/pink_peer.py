"""pink's QP differential IK as a peer of the improved method: a `FrameTask` on the tool
position with pink's `ConfigurationLimit`, one QP per control step, from the documented default
start (`PinkResolver`, `pink_run`). It needs the optional ``bench`` dependencies (pin-pink and a
QP solver): pip install 'redundancy[bench]'.

Its run is a `StrategyRun` whose trajectory reports the strokes as they were: pink keeps the
URDF's joint limits only, and a stroke it leaves is flagged, never clipped.
"""

from __future__ import annotations

import numpy as np

from redundancy.errors import InvalidInputError, RedundancyError
from redundancy.model.robot import AXES, Robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, time_grid
from redundancy.planning.starts import default_start
from redundancy.planning.tasks import Segment
from redundancy.resolution.laws import Resolver
from redundancy.resolution.state import evaluate
from redundancy.study.peers import StrategyRun

PINK_SOLVER = "daqp"  # the QP backend (any of qpsolvers' available_solvers)


def _pink():
    try:
        import pink
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask
    except ImportError as error:
        raise RedundancyError(
            "the pink peer needs pin-pink and a QP solver: pip install 'redundancy[bench]' "
            "(or pip install pin-pink daqp)"
        ) from error
    return pink, FrameTask, ConfigurationLimit


class PinkResolver(Resolver):
    """pink's differential IK on the robot, as a resolution law. Each control step solves, for
    Δq = v dt,

        min ½ ‖J Δq − e‖² + μ ‖Δq‖²   subject to pink's ConfigurationLimit on q,

    with e the tool's position error to the target point one step ahead (a `FrameTask` with
    position cost 1 and orientation cost 0; μ is pink's default Tikhonov damping), by the QP
    ``solver``; then ẋ = A v. The limits are the URDF's joint limits: pink knows nothing of
    actuator strokes (on the crane the joint limits are the strokes' images).
    """

    name = "pink QP differential IK"

    def __init__(self, robot: Robot, time_step: float = TIME_STEP, solver: str = PINK_SOLVER):
        pink, FrameTask, ConfigurationLimit = _pink()
        import qpsolvers

        if solver not in qpsolvers.available_solvers:
            raise InvalidInputError(
                f"QP solver {solver!r} is not installed; available: "
                f"{', '.join(qpsolvers.available_solvers) or 'none'}"
            )
        if not time_step > 0:
            raise InvalidInputError(f"time_step must be > 0 s; got {time_step}")
        self.robot, self.time_step, self.solver = robot, time_step, solver
        self._solve_ik = pink.solve_ik
        self.task = FrameTask(robot.tool_frame, position_cost=1.0, orientation_cost=0.0)
        self.limits = [ConfigurationLimit(robot.model)]
        self.configuration = pink.Configuration(robot.model, robot.data, robot.lower.copy())
        self._rows = [AXES.index(a) for a in robot.task_axes]

    def __repr__(self) -> str:
        return f"PinkResolver(time_step={self.time_step}, solver={self.solver!r})"

    def control_step(
        self, q: np.ndarray, target: np.ndarray, dt: float | None = None
    ) -> np.ndarray:
        """The joint velocity v (n,) pink commands at q (n,) to bring the tool to ``target``
        (m,), in m, one time step (``dt``, by default `time_step`) later: one control step."""
        configuration = self.configuration
        configuration.update(q)
        placement = configuration.get_transform_frame_to_world(self.robot.tool_frame)
        placement.translation[self._rows] = target
        self.task.set_target(placement)
        return self._solve_ik(
            configuration,
            [self.task],
            self.time_step if dt is None else dt,
            self.solver,
            limits=self.limits,
            safety_break=False,
        )

    def resolve(self, space, y_dot: np.ndarray) -> np.ndarray:
        """ẋ = A v (k, n) with v the step towards y + ẏ dt from each state."""
        targets = space.y + y_dot * self.time_step
        v = np.array([self.control_step(q, target) for q, target in zip(space.q, targets)])
        return (space.A @ v[..., None])[..., 0]

    def run(self, segment: Segment, start: np.ndarray, checked=None) -> Trajectory:
        """pink's motion along ``segment`` from ``start`` (n,), as it runs in a control loop on
        the uniform grid of steps dt of at most `time_step` (`time_grid`): q_k+1 = q_k + v_k dt
        with v_k aimed at y_d(t_k + dt); ẋ at each sample is A v_k."""
        robot = self.robot
        t = time_grid(segment, self.time_step)
        dt = t[1] - t[0]
        q = np.empty((len(t), robot.n))
        v = np.empty_like(q)
        q[0] = robot.configuration(start, "start")[0]
        for i, time in enumerate(t):
            v[i] = self.control_step(q[i], segment.position(time + dt), dt)
            if i + 1 < len(t):
                q[i + 1] = q[i] + v[i] * dt
        space = evaluate(robot, q)
        x_dot = (space.A @ v[..., None])[..., 0]
        checked = tuple(robot.actuators.names if checked is None else checked)
        return Trajectory.single(robot, segment, self, t, space, x_dot, checked)


def pink_run(
    robot: Robot,
    segment: Segment,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    solver: str = PINK_SOLVER,
) -> StrategyRun:
    """pink's QP differential IK along ``segment`` from the default start."""
    value, start = default_start(robot, segment, held)
    motion = PinkResolver(robot, time_step, solver).run(segment, start, checked)
    return StrategyRun(
        segment.name, f"pink QP IK ({solver})", tuple(float(v) for v in value), motion
    )
