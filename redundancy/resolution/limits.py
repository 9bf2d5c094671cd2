"""Limits: actuator strokes, joint ranges and the hydraulic circuit's limits, one margin and one
`Violation` for all.

The margin of a value to its limits [lower, upper] is min(value − lower, upper − value): the
distance inside (m, or rad for rotary actuators and revolute joints), negative past a limit. A
set of limits' margin is the least of its members'. Whoever checks limits (the integrators, both
searches, the bound, the playback) reads this one definition; a value within `TOLERANCE` past a
limit counts as inside. Messages give lengths in mm, angles in degrees, pressures in bar, flows
in L/min, speeds in m/s and accelerations in m/s².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from redundancy.model.hydraulics import Circuit, Flows, Supply
from redundancy.model.robot import Robot

TOLERANCE = 1e-9  # m or rad: a value this close past a limit counts as inside


SHOWN_ZERO = 1e-12  # SI units: what Newton's converged residual is (1e-12 m), shown as 0
WRITTEN_OUT = 1e9  # shown units: a value below is written out (30000 mm, not 3e+04 mm); one
# beyond is no machine's (1000 km) but a mistake's, and keeps its power of ten
# SI unit → (factor, shown unit) for messages
SHOWN = {
    "m": (1e3, " mm"),
    "rad": (180 / np.pi, "°"),
    "Pa": (1e-5, " bar"),
    "m³/s": (6e4, " L/min"),
    "m/s": (1.0, " m/s"),
    "m/s²": (1.0, " m/s²"),
}


def amount(value: float, unit: str) -> str:
    """``value`` in the SI ``unit`` (a key of `SHOWN`) as messages show it: m in mm, rad in
    degrees, Pa in bar, m³/s in L/min, to 4 significant digits, and from 10⁴ up (below
    `WRITTEN_OUT`) to the whole unit: 827.9 mm, 30000 mm; one below `SHOWN_ZERO` as 0 (a
    round-off's 1e-13 rad is no 6e-12°)."""
    factor, shown = SHOWN[unit]
    number = (0.0 if abs(value) < SHOWN_ZERO else value) * factor
    text = f"{number:z.4g}"
    if "e+" in text and abs(number) < WRITTEN_OUT:
        text = f"{number:z.0f}"
    return f"{text}{shown}"


@dataclass(frozen=True)
class Violation:
    """A limit passed over [start, end] (s): ``actuator`` (or a hydraulic quantity's name) at
    worst ``excess`` (in the SI ``unit``) past its ``bound`` ("lower" or "upper")."""

    actuator: str
    bound: str
    start: float
    end: float
    excess: float
    unit: str = "m"

    def __str__(self) -> str:
        return (
            f"{self.actuator} {amount(self.excess, self.unit)} past its {self.bound} limit "
            f"over t = {self.start:.2f}-{self.end:.2f} s"
        )


@dataclass(frozen=True)
class Limits:
    """Limits [lower, upper] (c,) on c of a state's n coordinates: ``columns`` (c,) index them,
    ``names`` name them, ``units`` (c,) give their SI units (keys of `SHOWN`)."""

    names: tuple[str, ...]
    columns: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    units: tuple[str, ...]

    @classmethod
    def strokes(
        cls, robot: Robot, checked: str | tuple[str, ...] | list[str] | None = None
    ) -> Limits:
        """The strokes of the actuators ``checked`` (default every one)."""
        actuators = robot.actuators
        names = actuators.names
        columns = np.array(actuators.rows(names if checked is None else checked), dtype=int)
        return cls(
            tuple(names[c] for c in columns),
            columns,
            actuators.lower[columns],
            actuators.upper[columns],
            tuple("rad" if rotary else "m" for rotary in actuators.rotary[columns]),
        )

    @classmethod
    def joints(cls, robot: Robot) -> Limits:
        """The joint ranges (from the URDF)."""
        return cls(
            tuple(robot.joint_names),
            np.arange(robot.n),
            robot.lower.copy(),
            robot.upper.copy(),
            tuple("rad" if rotary else "m" for rotary in robot.rotary_joints),
        )

    @classmethod
    def hydraulic(cls, robot: Robot, supply: Supply | None = None) -> Limits:
        """The circuit's limits on `hydraulic_values`: each cylinder's load
        pressure at most what the supply can serve, the pump flow at most its maximum, each
        cylinder's speed at most its maximum (`redundancy.model.hydraulics`), under ``supply``
        (default the machine's)."""
        circuit = robot.circuit()
        supply = supply or circuit.supply
        c = len(circuit.names)
        names = (
            *(f"{name} load pressure" for name in circuit.names),
            "pump flow",
            *(f"{name} speed" for name in circuit.names),
        )
        upper = np.concatenate(
            [
                np.full(c, supply.available(circuit.relief)),
                [circuit.pump_flow],
                circuit.max_speeds,
            ]
        )
        units = ("Pa",) * c + ("m³/s",) + ("m/s",) * c
        return cls(names, np.arange(2 * c + 1), np.full(2 * c + 1, -np.inf), upper, units)

    @classmethod
    def accelerations(cls, robot: Robot) -> Limits:
        """Each cylinder's acceleration within its maximum either way, −a_max ≤ ẍ ≤ a_max
        (m/s², `redundancy.model.hydraulics.Cylinder`), on accelerations ẍ (..., n)."""
        circuit = robot.circuit()
        a_max = circuit.max_accelerations
        names = tuple(f"{name} acceleration" for name in circuit.names)
        return cls(names, circuit.columns.copy(), -a_max, a_max, ("m/s²",) * len(names))

    def excess(self, values: np.ndarray) -> np.ndarray:
        """How far each checked value is past its limit, (..., c): positive past, negative
        inside, for values (..., n)."""
        checked = values[..., self.columns]
        return np.maximum(self.lower - checked, checked - self.upper)

    def margin(self, values: np.ndarray) -> np.ndarray:
        """The least margin over the checked values, (...,), for values (..., n)."""
        if not len(self.columns):
            return np.full(values.shape[:-1], np.inf)
        return -self.excess(values).max(axis=-1)

    def range_margin(self, lowest: np.ndarray, highest: np.ndarray) -> np.ndarray:
        """The least margin over ranges [lowest, highest] (..., n) of each coordinate, (...,)."""
        if not len(self.columns):
            return np.full(lowest.shape[:-1], np.inf)
        inside = np.minimum(
            lowest[..., self.columns] - self.lower, self.upper - highest[..., self.columns]
        )
        return inside.min(axis=-1)

    def violations(self, t: np.ndarray, values: np.ndarray) -> list[list[Violation]]:
        """Every interval over which a checked value is past its limit by more than
        `TOLERANCE`, for each of k sampled series values (k, T, n) at times t (k, T): a list per
        series, in order of time. All series are scanned at once."""
        found: list[list] = [[] for _ in values]  # (start, column, bound, the violation)
        checked = values[..., self.columns]
        for order, (bound, excess) in enumerate(
            (("lower", self.lower - checked), ("upper", checked - self.upper))
        ):
            outside = (excess > TOLERANCE).astype(np.int8)
            if not outside.any():  # the common case, found at the cost of one pass
                continue
            change = np.diff(outside, axis=1, prepend=0, append=0)
            # per series and column, in that order: each interval's start and stop in turn
            series, columns, edges = np.nonzero(change.transpose(0, 2, 1))
            for i, j, start, stop in zip(series[::2], columns[::2], edges[::2], edges[1::2]):
                violation = Violation(
                    self.names[j],
                    bound,
                    float(t[i, start]),
                    float(t[i, stop - 1]),
                    float(excess[i, start:stop, j].max()),
                    self.units[j],
                )
                found[i].append((violation.start, j, order, violation))
        return [[violation for *_, violation in sorted(f, key=lambda f: f[:3])] for f in found]


def hydraulic_values(circuit: Circuit, x_dot: np.ndarray, flows: Flows) -> np.ndarray:
    """What `Limits.hydraulic` bounds, (..., 2c + 1): each cylinder's load pressure (Pa), the
    pump flow (m³/s), each cylinder's speed (m/s), for actuator velocities ẋ (..., n) and the
    circuit's ``flows`` at them."""
    speeds = np.abs(x_dot[..., circuit.columns])
    return np.concatenate([flows.load, flows.pump_flow[..., None], speeds], axis=-1)
