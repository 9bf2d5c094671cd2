"""The one Pinocchio pass: positions and Jacobians of the tracked frames at a batch of states.

A robot tracks F frames: the tool and every actuator attachment point. For k states (q, and
optionally v) one pass per state computes the joint Jacobians, then reads each tracked frame's
world position p, its world-aligned point Jacobian J_p = ∂p/∂q and, with velocities, its rate
J̇_p. Everything else in the toolkit (task coordinates y and J, actuator strokes x and A, their
rates) is read from this one result.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

WORLD = pin.LOCAL_WORLD_ALIGNED


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
    """Pinocchio's kinematics of the tracked frames at a batch of k states.

    positions (k, F, 3) and jacobians (k, F, 3, n) of the F tracked frames, world-aligned; with
    velocities v (k, n) also their velocities (k, F, 3) and jacobian_rates (k, F, 3, n).
    ``slots`` maps a Pinocchio frame id to its index among the F.
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


def track(
    model: pin.Model,
    data: pin.Data,
    frames: list[int],
    slots: dict[int, int],
    q: np.ndarray,
    v: np.ndarray | None = None,
) -> Kinematics:
    """Kinematics of ``frames`` at the states q (k, n) and, if given, v (k, n)."""
    jacobian, placement = pin.getFrameJacobian, pin.updateFramePlacement
    rate = pin.getFrameJacobianTimeVariation
    k, count = len(q), len(frames)
    # Pinocchio's answers (copies, never views into data) are gathered in lists and stacked
    # once: cheaper than writing each into an array.
    jacobians, positions, rates = [], [], []
    for i in range(k):
        if v is None:
            pin.computeJointJacobians(model, data, q[i])
        else:
            pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
            rates += [rate(model, data, frame, WORLD) for frame in frames]
        jacobians += [jacobian(model, data, frame, WORLD) for frame in frames]
        positions += [placement(model, data, frame).translation for frame in frames]
    shape = (k, count, 6, model.nv)
    linear = np.array(jacobians).reshape(shape)[:, :, :3]
    position = np.array(positions).reshape(k, count, 3)
    if v is None:
        return Kinematics(q, None, position, linear, None, None, slots)
    velocities = (linear @ v[:, None, :, None])[..., 0]
    rates_linear = np.array(rates).reshape(shape)[:, :, :3]
    return Kinematics(q, v, position, linear, velocities, rates_linear, slots)
