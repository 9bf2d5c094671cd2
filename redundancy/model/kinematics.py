"""The one Pinocchio pass: positions and Jacobians of the tracked frames at a batch of states.

A robot tracks F frames: the tool and every actuator attachment point. For k states q the
compiled pass (`redundancy._core.Pass`, Pinocchio's C++ algorithms in one loop) computes the joint
Jacobians, then reads each tracked frame's world position p and its world-aligned Jacobian: the
point Jacobian J_p = ∂p/∂q and the angular rows J_ω. Everything else in the toolkit (task
coordinates y and J, actuator strokes x and A) is read from this one result.

With joint velocities v the same pass runs Pinocchio's `computeJointJacobiansTimeVariation`
instead, and adds each point's velocity ṗ = J_p v and Jacobian rate J̇_p = dJ_p/dt, mimic joints
included: J̇_p = J̇_v − [p]× J̇_ω − [ṗ]× J_ω from the rate of the spatial Jacobian [J_v; J_ω] (J_p
= J_v − [p]× J_ω), since Pinocchio's own world-aligned J̇ at a point leaves a mimic joint's share
out of the [ṗ]× J_ω term. A law solves for v after the pass; `Kinematics.moving` then runs the pass
with them, which in C++ costs less than deriving the rates from the stored Jacobians in numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from redundancy._core import Pass

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
    """What a pass reads: the compiled ``core`` over the robot's model and the tracked
    ``frames`` (ids), ``slots`` (a frame id → its index among them); ``declared`` keeps, for
    groups of actuator maps, how the core reads them from these frames."""

    core: Pass
    frames: list[int]
    slots: dict[int, int]
    declared: dict[tuple, tuple] = field(default_factory=dict, compare=False, repr=False)


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
        """These kinematics at joint velocities v (k, n): with velocities and Jacobian rates."""
        return track(self.tracking, self.q, v)

    def take(self, rows: np.ndarray) -> Kinematics:
        """The states ``rows`` (indices into the batch) alone."""
        taken: dict[str, Any] = {name: take(getattr(self, name), rows) for name in ARRAYS}
        return remade(self, **taken)

    @classmethod
    def joined(cls, parts: list[Kinematics]) -> Kinematics:
        """The batches ``parts`` (same tracking) as one, in order; rates where all have them."""
        arrays: dict[str, Any] = {name: join([getattr(p, name) for p in parts]) for name in ARRAYS}
        return remade(parts[0], **arrays)


ARRAYS = ("q", "positions", "jacobians", "angular", "v", "velocities", "jacobian_rates")


def remade(record: Any, **changes: Any) -> Any:
    """A frozen dataclass ``record`` with ``changes`` to its fields, as `dataclasses.replace`
    makes it (what was derived and cached on ``record`` not carried over), without its
    __init__: a batch's records are remade at every take and join, where one
    object.__setattr__ per field costs more than taking the arrays."""
    cls = type(record)
    if cls not in FIELD_NAMES:
        FIELD_NAMES[cls] = tuple(f.name for f in fields(cls))
    out = object.__new__(cls)
    values = vars(record)
    vars(out).update({name: values[name] for name in FIELD_NAMES[cls]}, **changes)
    return out


FIELD_NAMES: dict[type, tuple[str, ...]] = {}  # a dataclass's field names, read once


def take(array: np.ndarray | None, rows: np.ndarray) -> np.ndarray | None:
    """The rows ``rows`` (integer indices) of a batch's ``array`` (batch axis first), or None for
    None: by `numpy.ndarray.take`, which copies a batch of matrices in half the time indexing
    takes."""
    return None if array is None else array.take(rows, axis=0)


def join(arrays: list[np.ndarray | None]) -> np.ndarray | None:
    """Batches' ``arrays`` as one, in order, or None where one is None."""
    for array in arrays:  # a loop: a generator's frame costs more than the test
        if array is None:
            return None
    return np.concatenate(arrays)  # type: ignore[arg-type]


def track(tracking: Tracking, q: np.ndarray, v: np.ndarray | None = None) -> Kinematics:
    """Kinematics of the tracked frames at the states q (k, n) and, if given, v (k, n)."""
    positions, jacobians, angular, velocities, rates = tracking.core.kinematics(q, v)
    return Kinematics(tracking, q, positions, jacobians, angular, v, velocities, rates)
