"""The one Pinocchio pass: positions and Jacobians of the tracked frames at a batch of states.

A robot tracks F frames: the tool and every actuator attachment point. For k states q one pass
per state computes the joint Jacobians, then reads each tracked frame's world position p and its
world-aligned Jacobian: the point Jacobian J_p = ∂p/∂q and the angular rows J_ω. Everything else
in the toolkit (task coordinates y and J, actuator strokes x and A) is read from this one result.

Rates need no second pass. Once the joint velocities v are known (a law solves for them after
the pass), `Kinematics.moving` derives each point's velocity ṗ = J_p v and Jacobian rate J̇_p
from the stored Jacobians: column j of the world spatial Jacobian, c_j = (J_p,j + p × J_ω,j,
J_ω,j) at the world origin, moves with its body, ċ_j = V_j × c_j, where V_j = (v_o, ω) =
Σ_{i ≤ j} c_i v_i is the spatial velocity of joint j's body (its supporting columns come first
in Pinocchio's joint order). Hence

    J̇_p,j = ω × (J_p,j + p × J_ω,j) + v_o × J_ω,j + (ω × J_ω,j) × p + J_ω,j × ṗ.

Mimic joints share a column with the joint they follow, so for a model with mimic joints the
rates come from Pinocchio's `computeJointJacobiansTimeVariation` instead.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any, NamedTuple

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
class Tracking:
    """What a pass reads: the Pinocchio ``model`` and its ``data``, the tracked ``frames`` (ids)
    and ``slots`` (a frame id → its index among them)."""

    model: pin.Model
    data: pin.Data
    frames: list[int]
    slots: dict[int, int]

    @cached_property
    def mimic(self) -> bool:
        """Whether some joint of the model mimics another (shares its velocity column)."""
        return any("Mimic" in joint.shortname() for joint in self.model.joints)


@dataclass(frozen=True)
class Kinematics:
    """Pinocchio's kinematics of the tracked frames at a batch of k states.

    positions (k, F, 3), jacobians (k, F, 3, n) (linear, world-aligned at each point) and
    angular (k, F, 3, n) of the F tracked frames; with velocities v (k, n) also their
    velocities (k, F, 3) and jacobian_rates (k, F, 3, n).
    """

    tracking: Tracking
    q: np.ndarray
    positions: np.ndarray
    jacobians: np.ndarray
    angular: np.ndarray
    v: np.ndarray | None = None
    velocities: np.ndarray | None = None
    jacobian_rates: np.ndarray | None = None

    @property
    def slots(self) -> dict[int, int]:
        """A Pinocchio frame id → its index among the tracked frames."""
        return self.tracking.slots

    def point(self, frame: int) -> PointMotion:
        """Motion of the tracked frame ``frame``."""
        i = self.slots[frame]
        return PointMotion(
            self.positions[:, i],
            self.jacobians[:, i],
            None if self.velocities is None else self.velocities[:, i],
            None if self.jacobian_rates is None else self.jacobian_rates[:, i],
        )

    def moving(self, v: np.ndarray) -> Kinematics:
        """These kinematics at joint velocities v (k, n): velocities and Jacobian rates from
        the stored Jacobians (see the module docstring), without a second Pinocchio pass."""
        if self.tracking.mimic:
            return track(self.tracking, self.q, v)
        p, linear, angular = self.positions, self.jacobians, self.angular
        velocities = (linear @ v[:, None, :, None])[..., 0]
        at_origin = linear + np.cross(p[..., None], angular, axis=-2)
        columns = np.concatenate([at_origin, angular], axis=-2) * v[:, None, None, :]
        body = np.cumsum(columns, axis=-1)  # V_j = (v_o, ω) of each column's body
        v_o, omega = body[..., :3, :], body[..., 3:, :]
        cross = np.cross
        rates = (
            cross(omega, at_origin, axis=-2)
            + cross(v_o, angular, axis=-2)
            + cross(cross(omega, angular, axis=-2), p[..., None], axis=-2)
            + cross(angular, velocities[..., None], axis=-2)
        )
        return replace(self, v=v, velocities=velocities, jacobian_rates=rates)

    def take(self, rows: np.ndarray) -> Kinematics:
        """The states ``rows`` (indices into the batch) alone."""
        taken: dict[str, Any] = {name: take(getattr(self, name), rows) for name in ARRAYS}
        return replace(self, **taken)

    @classmethod
    def joined(cls, parts: list[Kinematics]) -> Kinematics:
        """The batches ``parts`` (same tracking) as one, in order; rates where all have them."""
        arrays: dict[str, Any] = {name: join([getattr(p, name) for p in parts]) for name in ARRAYS}
        return replace(parts[0], **arrays)


ARRAYS = ("q", "positions", "jacobians", "angular", "v", "velocities", "jacobian_rates")


def take(array: np.ndarray | None, rows: np.ndarray) -> np.ndarray | None:
    """The rows ``rows`` of a batch's ``array`` (batch axis first), or None for None."""
    return None if array is None else array[rows]


def join(arrays: list[np.ndarray | None]) -> np.ndarray | None:
    """Batches' ``arrays`` as one, in order, or None where one is None."""
    if any(array is None for array in arrays):
        return None
    return np.concatenate(arrays)  # type: ignore[arg-type]


def track(tracking: Tracking, q: np.ndarray, v: np.ndarray | None = None) -> Kinematics:
    """Kinematics of the tracked frames at the states q (k, n) and, if given, v (k, n)."""
    model, data, frames = tracking.model, tracking.data, tracking.frames
    jacobian, placement = pin.getFrameJacobian, pin.updateFramePlacement
    k, count = len(q), len(frames)
    # Pinocchio's answers (copies, never views into data) are gathered in lists and stacked
    # once: cheaper than writing each into an array.
    jacobians, positions, rates = [], [], []
    for i in range(k):
        if v is not None and tracking.mimic:
            pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
            rates += [
                pin.getFrameJacobianTimeVariation(model, data, frame, WORLD) for frame in frames
            ]
        else:
            pin.computeJointJacobians(model, data, q[i])
        jacobians += [jacobian(model, data, frame, WORLD) for frame in frames]
        positions += [placement(model, data, frame).translation for frame in frames]
    shape = (k, count, 6, model.nv)
    six = np.array(jacobians).reshape(shape)
    found = Kinematics(tracking, q, np.array(positions).reshape(k, count, 3), *np.split(six, 2, 2))
    if v is None:
        return found
    if not tracking.mimic:
        return found.moving(v)
    velocities = (found.jacobians @ v[:, None, :, None])[..., 0]
    rates_linear = np.array(rates).reshape(shape)[:, :, :3]
    return replace(found, v=v, velocities=velocities, jacobian_rates=rates_linear)
