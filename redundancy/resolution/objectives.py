"""What a strategy minimises: an objective is a law plus a measure along the motion.

The measure is a quantity at each state, computed from the state and its actuator velocities;
the objective reduces it over a motion to its peak (the paper's choice, Figs. 4a, 5a) or its
time integral. The paper's two improved solutions are `VELOCITY` (the law of least ẋᵀẋ, Eq. 24,
measured by ẋᵀẋ) and `ENERGY` (the law of least ẋᵀ M_H ẋ, Eq. 32, measured by ẋᵀ M_H ẋ, twice
the kinetic energy, Eq. 28). With a hydraulic circuit (`redundancy.model.hydraulics`) three
more follow the flow-weighted law (`MinFlow`): `FLOW`, the peak pump flow Q_P, and `LS_ENERGY`
and `CP_ENERGY`, the pump energy ∫ p_P Q_P dt under load sensing and constant pressure. The
energies need the forces F_H = M_H ẍ + N_H, hence ẍ: such an objective is ``dynamic``, measured
on finished motions (ẍ from their samples), not inside the integrator. An objective of your own
is one more `Objective`: every search (the sweep, the fast search) and, for a peak, the bound
take it as they take these.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.hydraulics import KILOJOULE, LITRES_PER_MINUTE
from redundancy.resolution.laws import MinFlow, MinKineticEnergy, MinVelocityNorm, Resolver
from redundancy.resolution.state import ActuatorSpace

REDUCTIONS = ("peak", "integral")


@dataclass(frozen=True)
class Objective:
    """A named objective: its ``resolver`` (the law the motion follows), its ``measure``
    (states, ẋ (k, n)) → (k,), and how a motion's measure is reduced: "peak" (the maximum) or
    "integral" (over time, trapezoidal). ``label`` and ``unit`` name the measure. A
    ``dynamic`` measure reads the forces ``space.F_H``, so it is taken on finished motions."""

    name: str
    resolver: Resolver
    measure: Callable[[ActuatorSpace, np.ndarray], np.ndarray]
    label: str
    unit: str
    reduction: str = "peak"
    dynamic: bool = False

    def __post_init__(self) -> None:
        if self.reduction not in REDUCTIONS:
            raise InvalidInputError(
                f"objective {self.name!r}: reduction {self.reduction!r} is not one of "
                f"{', '.join(REDUCTIONS)}"
            )

    def unit_of(self, actuators) -> str:
        """``unit`` on these actuators: ẋᵀẋ (`velocity_norm`) adds the squared rates of lengths
        (m²/s²) and of angles (rad²/s²), so that of rotary ones is in rad²/s², and of a mix in
        both, each actuator in its own."""
        rotary = [a.name for a in actuators if a.rotary]
        if self.measure is not velocity_norm or not rotary:
            return self.unit
        if len(rotary) == len(actuators):
            return "rad²/s²"
        return f"m²/s²; rad²/s² for {', '.join(rotary)}"

    @property
    def value_label(self) -> str:
        """What the objective's value over a motion is called: "peak ẋᵀẋ", or for an integral
        "∫ LS pump power dt"."""
        return f"peak {self.label}" if self.reduction == "peak" else f"∫ {self.label} dt"

    def value_unit(self, actuators) -> str:
        """The unit of that value on these actuators: the measure's (`unit_of`), or for an
        integral the measure's times a second (kW·s is kJ, W·s is J)."""
        unit = self.unit_of(actuators)
        if self.reduction == "peak":
            return unit
        return {"kW": "kJ", "W": "J"}.get(unit, f"{unit}·s")

    def value_axis(self, actuators) -> str:
        """That value with its unit, as a figure's axis names it: "peak ẋᵀẋ (m²/s²)"."""
        return f"{self.value_label} ({self.value_unit(actuators)})"

    def over_segments(self, values: Sequence[float | None]) -> float | None:
        """The objective over consecutive segments from each one's value (None where unknown):
        the largest peak known, or the sum of the integrals where every one is known."""
        known = [v for v in values if v is not None]
        if self.reduction == "peak":
            return max(known) if known else None
        return sum(known) if known and len(known) == len(values) else None

    def reduce(
        self, t: np.ndarray, values: np.ndarray, jumps: np.ndarray | None = None
    ) -> np.ndarray:
        """The objective of k motions from the measure ``values`` (k, T) at times t (k, T),
        sampled at steps and their midpoints where the path's ``jumps`` are given
        (`integral`)."""
        if self.reduction == "peak":
            return values.max(axis=1)
        return integral(t, values, jumps)


def integral(t: np.ndarray, values: np.ndarray, jumps: np.ndarray | None = None) -> np.ndarray:
    """∫ values dt (k,) for samples values (k, T) at times t (k, T): by the trapezoidal rule;
    or, given the times ``jumps`` (j,) where the path's ẏ_d jumps (samples at t₀, then each
    step's middle and end, no step across a break of the path: an adaptive motion's sparse
    samples, `redundancy.planning.integrate`), by Simpson's rule on every step,
    h/6 (f₀ + 4 f_½ + f₁): exact for cubics, an error of O(h⁵) a step where the trapezoids
    between the same samples err by O(h³), which on an adaptive motion's few long steps is
    percents (1.9 % on a 4R arm's joint speeds over 3 steps, against 5e-5 by Simpson). A step
    from a jump (a polyline's corner turned at speed), whose sample there is the piece
    before's, takes its middle alone, h f_½ (exact for lines). A motion's repeated last
    samples (h = 0) add nothing."""
    if jumps is None:
        return np.sum((values[:, 1:] + values[:, :-1]) / 2 * np.diff(t, axis=1), axis=1)
    ends, middles = values[:, ::2], values[:, 1::2]
    steps = np.diff(t[:, ::2], axis=1)
    simpson = (ends[:, :-1] + 4 * middles + ends[:, 1:]) / 6
    at_jump = np.abs(t[:, :-1:2, None] - jumps).min(axis=-1, initial=np.inf) <= 1e-9 * t.max()
    return np.sum(np.where(at_jump, middles, simpson) * steps, axis=1)


def velocity_norm(space: ActuatorSpace, x_dot: np.ndarray) -> np.ndarray:
    """ẋᵀẋ (k,), m²/s²."""
    return np.einsum("ki,ki->k", x_dot, x_dot)


def kinetic(space: ActuatorSpace, x_dot: np.ndarray) -> np.ndarray:
    """ẋᵀ M_H ẋ (k,) = twice the kinetic energy (Eq. 28), J."""
    return np.einsum("ki,kij,kj->k", x_dot, space.M_H, x_dot)


def pump_flow(space: ActuatorSpace, x_dot: np.ndarray) -> np.ndarray:
    """Pump flow Q_P = Σ Q (k,), L/min."""
    return space.robot.circuit().flow_rates(x_dot) / LITRES_PER_MINUTE


def pump_power(supply: str) -> Callable[[ActuatorSpace, np.ndarray], np.ndarray]:
    """The measure p_P Q_P (k,) in kW (its integral in kJ) under the circuit's ``supply``,
    "load_sensing" or "constant_pressure", with the forces F_H of the states: a partial of a
    module function, so that an objective of it is sent to another process as any other."""
    return partial(_pump_power, supply)


def _pump_power(supply: str, space: ActuatorSpace, x_dot: np.ndarray) -> np.ndarray:
    circuit = space.robot.circuit()
    return circuit.flows(x_dot, space.F_H).power(getattr(circuit, supply)) / KILOJOULE


VELOCITY = Objective("velocity", MinVelocityNorm(), velocity_norm, "ẋᵀẋ", "m²/s²")
ENERGY = Objective("energy", MinKineticEnergy(), kinetic, "ẋᵀ M_H ẋ", "J")
FLOW = Objective("flow", MinFlow(), pump_flow, "pump flow Q_P", "L/min")
LS_ENERGY = Objective(
    "ls_energy",
    MinFlow(),
    pump_power("load_sensing"),
    "LS pump power",
    "kW",
    "integral",
    dynamic=True,
)
CP_ENERGY = Objective(
    "cp_energy",
    MinFlow(),
    pump_power("constant_pressure"),
    "CP pump power",
    "kW",
    "integral",
    dynamic=True,
)
OBJECTIVES = {o.name: o for o in (VELOCITY, ENERGY, FLOW, LS_ENERGY, CP_ENERGY)}


def objectives_of(given: object) -> tuple[Objective, ...]:
    """``given``, an objective or its name or a sequence of them, as Objectives; the error names
    the one that is none and lists the choices."""
    if isinstance(given, str | Objective) or not isinstance(given, Sequence):
        given = (given,)
    return tuple(objective(o) for o in given)


def objective(name: object) -> Objective:
    """The objective called ``name`` (an `Objective` is taken as it is); the error lists the
    choices."""
    if isinstance(name, Objective):
        return name
    if not isinstance(name, str) or name not in OBJECTIVES:
        raise InvalidInputError(
            f"unknown objective {name!r}; objectives: {', '.join(OBJECTIVES)}, or an Objective"
        )
    return OBJECTIVES[name]
