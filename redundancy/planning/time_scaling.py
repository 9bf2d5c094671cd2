"""Time scaling: the shortest duration of a resolved path within the hydraulic circuit's limits.

A strategy's motion fixes a geometric path; how fast it can be run is a separate question. The
path is taken as the cylinders' strokes x(s) and the pumped volume V(s), s ∈ [0, 1] the motion's
normalised time, V the oil the pump has delivered (dV = Σ A_A dx where a cylinder extends,
A_B |dx| where it retracts, `redundancy.model.hydraulics`). Along a re-timed path s(t)

    |ẋ_i| = |x_i'| ṡ ≤ v_max,i,   |ẍ_i| = |x_i'' ṡ² + x_i' s̈| ≤ a_max,i,   Q_P = V' ṡ ≤ Q_max,

so the pump's flow is a velocity limit on the coordinate V. TOPP-RA (Pham & Pham, IEEE T-RO
34(3), 2018; the ``toppra`` package) finds the fastest s(t) from rest to rest, with constant s̈
between its grid points. The limits hold at its grid points; where the dense re-timed samples
pass one by a hair, the timing is stretched uniformly by the least factor k that brings it back
(velocities scale by 1/k, accelerations by 1/k²). Actuators that are not cylinders are left
unconstrained.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError, RedundancyError
from redundancy.model.robot import Robot
from redundancy.model.values import is_whole
from redundancy.planning.integrate import FAILED, Trajectory

SAMPLES = 400  # path points fed to TOPP-RA (at most; fewer if the motion has fewer)


@dataclass(frozen=True)
class Retimed:
    """The fastest timing of one motion's path: its ``duration`` (s), and the re-timed strokes
    x, velocities ẋ and accelerations ẍ of the cylinders (T, c) with the pump flow Q_P (T,) from
    those velocities, at times t (T,)."""

    duration: float
    t: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    pump_flow: np.ndarray

    def usage(self, robot: Robot) -> dict[str, float]:
        """The largest share of each limit the re-timed motion uses (1 = at the limit):
        "speed", "acceleration" and "pump flow"."""
        circuit = robot.circuit()
        return {
            "speed": float((np.abs(self.x_dot) / circuit.max_speeds).max()),
            "acceleration": float((np.abs(self.x_ddot) / circuit.max_accelerations).max()),
            "pump flow": float(self.pump_flow.max() / circuit.pump_flow),
        }


def pumped_volume(robot: Robot, x: np.ndarray) -> np.ndarray:
    """V (T,) m³, the oil delivered along strokes x (T, n) of all actuators, from V = 0."""
    circuit = robot.circuit()
    oil = circuit.cylinder_flows(np.diff(x[:, circuit.columns], axis=0)).sum(axis=1)
    return np.concatenate([[0.0], np.cumsum(oil)])


def shortest_duration(motion: Trajectory, row: int = 0, samples: int = SAMPLES) -> Retimed:
    """The fastest timing, from rest to rest, of the path of motion ``row`` within the
    cylinders' speeds and accelerations and the pump's flow (see the module docstring); a
    motion that failed has no path to time (`InvalidInputError`)."""
    if not is_whole(row, 0, len(motion.t) - 1):
        raise InvalidInputError(
            f"row must be one of the {len(motion.t)} motions' rows; got {row!r}"
        )
    if not is_whole(samples, 3):
        raise InvalidInputError(f"samples must be a whole number ≥ 3; got {samples!r}")
    if motion.failed[row]:
        raise InvalidInputError(
            f"motion {row} along segment {motion.segment.name} failed, {FAILED}: it has no "
            "path to time"
        )
    import toppra  # its algorithms and constraints come with it

    robot = motion.robot
    circuit = robot.circuit()
    t = motion.t[row]
    last = int(motion.counts[row])  # a motion repeats its last sample to pad
    chosen = np.unique(np.linspace(0, last - 1, min(samples, last)).round().astype(int))
    x = motion.x[row, chosen]
    s = t[chosen] / t[last - 1]
    strokes = x[:, circuit.columns]
    volume = pumped_volume(robot, x)
    path = toppra.SplineInterpolator(s, np.column_stack([strokes, volume]))
    speeds = np.append(circuit.max_speeds, circuit.pump_flow)
    accelerations = np.append(circuit.max_accelerations, np.inf)
    velocity = toppra.constraint.JointVelocityConstraint(np.column_stack([-speeds, speeds]))
    acceleration = toppra.constraint.JointAccelerationConstraint(
        np.column_stack([-accelerations, accelerations])
    )
    instance = toppra.algorithm.TOPPRA(
        [velocity, acceleration],
        path,
        gridpoints=np.linspace(0, 1, 2 * len(s) + 1),
        parametrizer="ParametrizeConstAccel",
    )
    timing = instance.compute_trajectory(0, 0)
    if timing is None:
        raise RedundancyError(f"TOPP-RA found no timing of segment {motion.segment.name}'s path")
    times = np.linspace(0.0, timing.duration, 4 * len(s) + 1)
    c = len(circuit.columns)
    state, rate, second = (timing(times, order)[:, :c] for order in (0, 1, 2))
    retimed = Retimed(
        float(timing.duration), times, state, rate, second, circuit.cylinder_flows(rate).sum(1)
    )
    usage = retimed.usage(robot)
    k = max(1.0, usage["speed"], usage["pump flow"], np.sqrt(usage["acceleration"]))
    return Retimed(
        retimed.duration * k,
        times * k,
        state,
        rate / k,
        second / k**2,
        retimed.pump_flow / k,
    )
