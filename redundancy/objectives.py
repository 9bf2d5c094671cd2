"""What a strategy minimises: the peak over a motion of ẋᵀẋ or of ẋᵀ M_H ẋ, each with the
pseudoinverse that minimises it instantaneously (the paper's two improved solutions)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.resolvers import MinKineticEnergy, MinVelocityNorm, Resolver
from redundancy.simulate import Trajectory


@dataclass(frozen=True)
class Objective:
    """A named objective: its resolver, the per-sample measure along a motion (k, T), a label."""

    name: str
    resolver: Resolver
    measure: Callable[[Trajectory], np.ndarray]
    label: str
    unit: str

    def peak(self, trajectory: Trajectory) -> np.ndarray:
        """The objective's peak over each motion (k,)."""
        return self.measure(trajectory).max(axis=1)


VELOCITY = Objective("velocity", MinVelocityNorm(), lambda tr: tr.velocity_norm, "ẋᵀẋ", "m²/s²")
ENERGY = Objective("energy", MinKineticEnergy(), lambda tr: tr.kinetic, "ẋᵀ M_H ẋ", "J")
OBJECTIVES = {o.name: o for o in (VELOCITY, ENERGY)}


def objective(name: str) -> Objective:
    """The objective called ``name``; the error lists the choices."""
    if name not in OBJECTIVES:
        raise InvalidInputError(f"unknown objective {name!r}; objectives: {', '.join(OBJECTIVES)}")
    return OBJECTIVES[name]
