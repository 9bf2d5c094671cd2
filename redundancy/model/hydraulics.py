"""The hydraulic circuit: cylinders, the pump's supply, and the quasi-static meter-in model.

Each hydraulic actuator is a double-acting cylinder of bore D and rod d, with the chamber areas

    A_A = π D² / 4 (piston side),        A_B = π (D² − d²) / 4 (rod side).

For its velocity ẋ and its force F (= F_H, Eq. 21: gravity, payload and inertia; positive when
it pushes the cylinder longer), the valve meters oil into the chamber that grows and lets the
other one drain to tank at p_T:

    ẋ ≥ 0:  Q = A_A ẋ,     p_L = (F + p_T A_B) / A_A
    ẋ < 0:  Q = A_B |ẋ|,   p_L = (−F + p_T A_A) / A_B

Where p_L < p_T the load drives the cylinder (overrunning): p_L counts as p_T and is flagged.
The pump delivers Q_P = Σ Q at the pressure its supply sets:

    load sensing (LS):       p_P = max over moving cylinders of p_L + Δp_LS
    constant pressure (CP):  p_P = p_S

and spends the power P = p_P Q_P, the energy E = ∫ P dt; of it Σ p_L Q reaches the cylinders
and P − Σ p_L Q is lost throttling in the valves. A supply of your own is a `Supply` subclass.

The circuit's limits: each load pressure at most what the supply can give (the relief pressure
less Δp_LS under LS, p_S under CP), the pump flow at most its maximum, and each cylinder's speed
at most its maximum. Inside, values are SI (m, m², m³/s, Pa, W, J); files and reports use mm,
bar, L/min and kJ.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.schema import CylinderTable, Hydraulics, read_toml, validate

BAR = 1e5  # Pa
LITRES_PER_MINUTE = 1e-3 / 60  # m³/s
MM = 1e-3  # m
KILOJOULE = 1e3  # J
SUPPLIES = ("LS", "CP")  # the supplies' names: load sensing, constant pressure
MOVING = 1e-9  # m/s: a cylinder slower than this does not count as moving for LS


@dataclass(frozen=True)
class Cylinder:
    """A double-acting cylinder: ``bore`` D and ``rod`` d (m), its ``max_speed`` (m/s) and
    ``max_acceleration`` (m/s²)."""

    bore: float
    rod: float
    max_speed: float
    max_acceleration: float

    @property
    def piston_area(self) -> float:
        """A_A = π D² / 4, m²."""
        return math.pi * self.bore**2 / 4

    @property
    def rod_side_area(self) -> float:
        """A_B = π (D² − d²) / 4, m²."""
        return math.pi * (self.bore**2 - self.rod**2) / 4


class Supply(ABC):
    """How the pump sets its pressure from the cylinders' load pressures."""

    name: str

    @abstractmethod
    def pressure(self, load: np.ndarray, moving: np.ndarray) -> np.ndarray:
        """Pump pressure p_P (k,) in Pa for load pressures p_L (k, c) in Pa, where ``moving``
        (k, c) marks the cylinders that move."""

    @abstractmethod
    def available(self, relief: float) -> float:
        """The highest load pressure the supply can serve (Pa) under the relief pressure."""


@dataclass(frozen=True)
class LoadSensing(Supply):
    """LS: the pump follows the highest moving load pressure plus the ``margin`` Δp_LS (Pa)."""

    margin: float
    name: str = "LS"

    def pressure(self, load: np.ndarray, moving: np.ndarray) -> np.ndarray:
        highest = np.where(moving, load, -np.inf).max(axis=-1, initial=-np.inf)
        return np.where(np.isfinite(highest), highest + self.margin, 0.0)

    def available(self, relief: float) -> float:
        return relief - self.margin


@dataclass(frozen=True)
class ConstantPressure(Supply):
    """CP: the pump holds the supply pressure p_S (Pa) whatever the loads."""

    pressure_level: float
    name: str = "CP"

    def pressure(self, load: np.ndarray, moving: np.ndarray) -> np.ndarray:
        return np.full(load.shape[:-1], self.pressure_level)

    def available(self, relief: float) -> float:
        return min(self.pressure_level, relief)


@dataclass(frozen=True)
class Flows:
    """The circuit along k states: per cylinder the flow Q (k, c) m³/s, the load pressure p_L
    (k, c) Pa (at least p_T) and where it is ``overrunning`` (k, c); ``moving`` (k, c)."""

    flow: np.ndarray
    load: np.ndarray
    overrunning: np.ndarray
    moving: np.ndarray

    @property
    def pump_flow(self) -> np.ndarray:
        """Q_P = Σ Q (k,), m³/s."""
        return self.flow.sum(axis=-1)

    @property
    def useful_power(self) -> np.ndarray:
        """Σ p_L Q (k,), W: the hydraulic power that reaches the cylinders."""
        return (self.load * self.flow).sum(axis=-1)

    def pump_pressure(self, supply: Supply) -> np.ndarray:
        """p_P (k,) in Pa under ``supply``."""
        return supply.pressure(self.load, self.moving)

    def power(self, supply: Supply) -> np.ndarray:
        """P = p_P Q_P (k,), W, under ``supply``."""
        return self.pump_pressure(supply) * self.pump_flow

    def loss(self, supply: Supply) -> np.ndarray:
        """Throttling loss P − Σ p_L Q (k,), W, under ``supply``."""
        return self.power(supply) - self.useful_power


BEYOND_RELIEF = 2.0  # × the relief pressure: a load pressure beyond it no circuit bears


@dataclass(frozen=True, eq=False)
class Circuit:
    """A machine's hydraulics: ``cylinders`` by actuator name (in actuator order) with their
    ``columns`` among the actuators, the machine's own ``supply``, both supplies' parameters for
    comparison (``load_sensing``, ``constant_pressure``), the ``relief`` pressure and the tank
    pressure ``tank`` (Pa), and the pump's maximum flow ``pump_flow`` (m³/s)."""

    names: tuple[str, ...]
    columns: np.ndarray
    cylinders: tuple[Cylinder, ...]
    supply: Supply
    load_sensing: LoadSensing
    constant_pressure: ConstantPressure
    relief: float
    pump_flow: float
    tank: float

    @property
    def supplies(self) -> tuple[Supply, Supply]:
        """Both supplies the toolkit compares, in `SUPPLIES`' order: load sensing, constant
        pressure."""
        return self.load_sensing, self.constant_pressure

    def unphysical(self, load_pressure: float) -> bool:
        """Whether a load pressure (Pa) is beyond the circuit's physics: above `BEYOND_RELIEF` ×
        the relief pressure, the valve opens long before. Such a value is the quasi-static
        model's where a motion leaves its strokes (a linkage near its toggle), not the
        machine's: it is flagged, never reported as a result."""
        return load_pressure > BEYOND_RELIEF * self.relief

    def _each(self, name: str) -> np.ndarray:
        return np.array([getattr(c, name) for c in self.cylinders])

    piston_areas = property(lambda self: self._each("piston_area"), doc="A_A (c,), m².")
    rod_side_areas = property(lambda self: self._each("rod_side_area"), doc="A_B (c,), m².")
    max_speeds = property(lambda self: self._each("max_speed"), doc="Maximum speeds (c,), m/s.")
    max_accelerations = property(
        lambda self: self._each("max_acceleration"), doc="Maximum accelerations (c,), m/s²."
    )

    def cylinder_flows(self, v: np.ndarray) -> np.ndarray:
        """Q (..., c) m³/s for cylinder velocities v (..., c): A_A v extending, A_B |v|
        retracting (or the oil volumes for stroke changes v, m)."""
        return np.where(v >= 0, self.piston_areas * v, -self.rod_side_areas * v)

    def flows(self, x_dot: np.ndarray, forces: np.ndarray) -> Flows:
        """The meter-in model (module docstring) at actuator velocities ẋ (..., n) m/s and
        forces F (..., n) N."""
        v, force = x_dot[..., self.columns], forces[..., self.columns]
        a, b, p_t = self.piston_areas, self.rod_side_areas, self.tank
        extending = v >= 0
        flow = self.cylinder_flows(v)
        load = np.where(extending, (force + p_t * b) / a, (p_t * a - force) / b)
        overrunning = load < p_t
        moving = np.abs(v) > MOVING
        return Flows(flow, np.maximum(load, p_t), overrunning & moving, moving)

    def flow_rates(self, x_dot: np.ndarray) -> np.ndarray:
        """Pump flow Q_P (...,) in m³/s at actuator velocities ẋ (..., n): it needs no forces."""
        return self.cylinder_flows(x_dot[..., self.columns]).sum(axis=-1)


def circuit_from_table(
    table: object,
    source: str,
    actuators: list[str],
    rotary: list[bool],
    declared: dict[str, CylinderTable] | None = None,
    declared_in: str = "",
    dropped: list[str] | tuple[str, ...] = (),
) -> Circuit:
    """A `Circuit` from a ``[hydraulics]`` table (`redundancy.model.schema.Hydraulics`, schema
    in the README), read from ``source``, for a robot with actuators ``actuators`` (``rotary``
    marks angles, which cylinders cannot drive), with the cylinders ``declared`` beside the
    actuators (in ``declared_in``, a URDF's transmissions) besides the table's own; a cylinder
    declared in both is an error. The cylinders of the actuators ``dropped`` (on locked joints)
    are left out."""
    given = validate(Hydraulics, table, source, "hydraulics")
    where = f"{source}: [hydraulics]"
    declared = declared or {}
    both = sorted(set(given.cylinders) & set(declared))
    if both:
        raise InvalidInputError(
            f"{where}: cylinders {both} are declared here and in {declared_in}; keep one"
        )
    places = {name: f"{where} cylinders.{name}" for name in given.cylinders}
    places |= {name: f"{declared_in} transmission {name!r}" for name in declared}
    cylinders = {  # a dropped actuator's cylinder (its joint locked) goes with it
        name: cylinder
        for name, cylinder in {**given.cylinders, **declared}.items()
        if name not in dropped
    }
    if not cylinders:
        raise InvalidInputError(
            f"{where}: no cylinders; declare [hydraulics.cylinders.<actuator>] tables or "
            f"<cylinder> elements in the transmissions; actuators: {', '.join(actuators)}"
        )
    for name in cylinders:
        if name not in actuators:
            raise InvalidInputError(f"{places[name]}: no actuator {name!r}; actuators: {actuators}")
        if rotary[actuators.index(name)]:
            raise InvalidInputError(f"{places[name]}: actuator {name!r} is rotary, not a cylinder")
    names = sorted(cylinders, key=actuators.index)
    load_sensing = LoadSensing(given.ls_margin * BAR)
    constant_pressure = ConstantPressure(given.cp_pressure * BAR)
    return Circuit(
        tuple(names),
        np.array([actuators.index(name) for name in names], dtype=int),
        tuple(
            Cylinder(c.bore * MM, c.rod * MM, c.max_speed, c.max_acceleration)
            for c in (cylinders[name] for name in names)
        ),
        load_sensing if given.supply == "LS" else constant_pressure,
        load_sensing,
        constant_pressure,
        given.relief * BAR,
        given.pump_flow * LITRES_PER_MINUTE,
        given.tank * BAR,
    )


def read_hydraulics_file(path: Path) -> object:
    """The ``[hydraulics]`` table of a TOML file (``--hydraulics FILE``)."""
    content = read_toml(path, "hydraulics file")
    if "hydraulics" not in content:
        raise InvalidInputError(f"{path}: no [hydraulics] table")
    return content["hydraulics"]
