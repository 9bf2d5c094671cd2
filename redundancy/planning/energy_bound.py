"""The energy bound: the motion along a segment of least pump energy over every history of the
held actuator, with every stroke and every limit of the hydraulic circuit kept.

Dynamic programming over a grid of the held actuator, as Nurmi & Mattila (Energies 10(5) 647,
2017) did for a forestry crane:

- nodes t_j = j h, h = t_f / N; at each, the configurations q(r) that solve y(q) = y_d(t_j),
  x_h(q) = r (Eqs. 6, 10) are found by Newton's method (continued from node to node, seeded
  afresh where that misses) at `EXACT` held strokes r over the held actuator's stroke, so the
  task is tracked exactly at every node; between them x(r) and the forces are cubic splines in
  r (their error, below 5e-5 m and largest at the ends of the stroke, is measured in
  tests/test_hydraulics.py). A held stroke whose
  neighbours miss the task or leave the joint ranges, or that puts a checked stroke past its
  limit, is excluded;
- a transition from r at t_j to r' at t_j+1 moves every actuator at ẋ = (x_j+1(r') − x_j(r))/h
  (so J_H ẋ = ẏ_d to first order, Eq. 16) against the mean of both nodes' forces F_H at rest,
  A⁻ᵀ G (Eq. 23 without velocity terms); its energy is h p_P Q_P from the circuit's meter-in
  model (`redundancy.model.hydraulics`), and it is excluded where a load pressure, the pump flow
  or a cylinder speed passes its limit;
- the least energy to each node is the least over its predecessors; the start is free. The
  first pass spans the stroke with `SPANNING` values; each later one spans a band `NARROWING`
  times as wide around the last path with `VALUES` values (iterative dynamic programming), so
  the held strokes end up resolved to a fraction of a millimetre.

Why dynamic programming and not the direct transcription of `redundancy.planning.bound`: the
load-sensing pump pressure is a maximum over the moving cylinders and the overrunning clamp
is a kink, so the cost is not differentiable where the optimum tends to lie, and the circuit's
limits cut the feasible set into pieces. The problem is not convex; dynamic programming finds
the least energy over its grid globally, whatever its shape.

The forces leave out inertia and velocity terms (M_H ẍ and the Coriolis part of N_H): they
would make the stage cost depend on three nodes. On the paper's crane they change the pump
energy of the strategies by well under 1 % (tests/test_hydraulics.py measures it); the
strategies' energies are computed with them. The bound converges as the grid is refined:
`EnergyOptimum.change` is the relative change of the energy from the previous grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from redundancy.errors import InvalidInputError
from redundancy.model.hydraulics import Supply
from redundancy.model.robot import Robot
from redundancy.planning.ik import (
    FOUND,
    ITERATIONS,
    held_indices,
    inverse_kinematics,
    newton,
)
from redundancy.planning.refinement import Refined, checked_grids
from redundancy.planning.tasks import Segment
from redundancy.resolution.limits import TOLERANCE, Limits, hydraulic_values
from redundancy.resolution.state import evaluate, regularised

GRIDS = (50, 100)  # intervals N of the successive grids
EXACT = 81  # held strokes per node where the configuration is solved for, over the stroke
SPANNING = 161  # held values per node of the first pass, over the whole stroke
VALUES = 121  # held values per node of every later pass, over a narrowing band
PASSES = 10  # passes per grid, each on a narrower band around the last pass's path
NARROWING = 0.35  # each band's half-width is this fraction of the one before


@dataclass(frozen=True)
class EnergyGrid:
    """The least energy (J) on one grid of ``intervals`` × ``values``."""

    intervals: int
    values: int
    energy: float
    success = True  # dynamic programming has no solver to fail: a grid without a path raises

    @property
    def optimum(self) -> float:
        """The least energy: what `Refined` judges the grid's convergence by."""
        return self.energy


@dataclass(frozen=True)
class EnergyOptimum(Refined):
    """The motion of least pump energy under ``supply`` on the finest grid: node times t
    (N + 1,) s and held strokes r (N + 1,) m, its ``energy`` (J), and every grid's least
    energy."""

    segment: Segment
    supply: Supply
    held: str
    t: np.ndarray
    r: np.ndarray
    grids: tuple[EnergyGrid, ...]

    @property
    def energy(self) -> float:
        """The least pump energy on the finest grid, J."""
        return self.optimum


def _nodes(robot: Robot, segment: Segment, row: int, values: np.ndarray, t: np.ndarray):
    """Configurations q (N + 1, G, n) inside the joint ranges reaching y_d(t_j) with the held
    stroke at each of ``values`` (G,), and where they were found (N + 1, G): projected Newton
    steps (`newton`, bounded) from the previous node's configuration, then, where that misses,
    from the configuration found at the nearest held stroke of the same node, or from
    `inverse_kinematics`'s spread of seeds where none was found. Keeping to the joint ranges
    keeps to one assembly branch: a cylinder's length is the same at q and −q."""
    held = robot.actuators.names[row]
    points = segment.position(t)
    q = np.empty((len(t), len(values), robot.n))
    found = np.zeros((len(t), len(values)), dtype=bool)
    target = np.column_stack([np.empty((len(values), robot.m)), values])
    for j, point in enumerate(points):
        target[:, : robot.m] = point
        if j:
            q[j], residual, _ = newton(robot, q[j - 1], [row], target, ITERATIONS, bounded=True)
            found[j] = residual < FOUND
        missing = np.flatnonzero(~found[j])
        if not found[j].any():
            seeded = inverse_kinematics(robot, point, [held], values[missing, None])
            q[j, missing], found[j, missing] = seeded.q, seeded.reached
        elif missing.size:
            known = np.flatnonzero(found[j])
            nearest = known[np.argmin(np.abs(values[missing, None] - values[known]), axis=1)]
            q[j, missing], residual, _ = newton(
                robot, q[j, nearest], [row], target[missing], ITERATIONS, bounded=True
            )
            found[j, missing] = residual < FOUND
    return q, found


class Tables:
    """Strokes x and forces F_H at rest (A⁻ᵀ G) as functions of the held stroke r at every node:
    exact at the `EXACT` solved strokes, cubic splines in r between usable neighbours."""

    def __init__(self, robot, segment, row, strokes: Limits, t: np.ndarray):
        actuator = robot.actuators[robot.actuators.names[row]]
        self.values = np.linspace(actuator.lower, actuator.upper, EXACT)
        q, found = _nodes(robot, segment, row, self.values, t)
        flat = q.reshape(-1, robot.n)
        space, bad = regularised(evaluate(robot, flat))
        usable = found.ravel() & ~bad & (Limits.joints(robot).margin(flat) >= -TOLERANCE)
        forces = np.where(usable[:, None], space.N_H, 0.0)  # A⁻ᵀ G at rest
        shape = (len(t), EXACT, robot.n)
        self.x, self.forces = space.x.reshape(shape), forces.reshape(shape)
        self.usable = usable.reshape(shape[:2])
        self.strokes = strokes
        # per node, a spline through the usable strokes (an interval is used only where both
        # its ends are usable, see `at`)
        self.splines = [
            CubicSpline(self.values[ok], np.concatenate([x[ok], f[ok]], axis=1), axis=0)
            if ok.sum() >= 2
            else None
            for x, f, ok in zip(self.x, self.forces, self.usable)
        ]

    def at(self, r: np.ndarray):
        """x, F_H (N + 1, G, n) and where usable (N + 1, G) at held strokes r (N + 1, G)."""
        index = np.clip(np.searchsorted(self.values, r) - 1, 0, EXACT - 2)
        node = np.arange(len(r))[:, None]
        usable = self.usable[node, index] & self.usable[node, index + 1]
        both = np.stack(
            [
                np.zeros((len(row), 2 * self.x.shape[-1])) if spline is None else spline(row)
                for spline, row in zip(self.splines, r)
            ]
        )
        n = self.x.shape[-1]
        x, forces = both[..., :n], both[..., n:]
        usable &= self.strokes.margin(x) >= -TOLERANCE
        return x, forces, usable


def _pass(robot: Robot, supply: Supply, tables: Tables, t: np.ndarray, values: np.ndarray):
    """Dynamic programming over the held strokes values (N + 1, G) at the node times t: the
    least energy (J, inf where nothing is feasible) and its held strokes at the nodes."""
    intervals, count = len(t) - 1, values.shape[1]
    x, forces, usable = tables.at(values)
    circuit, limits, h = robot.circuit(), Limits.hydraulic(robot, supply), t[1]
    cost = np.where(usable[0], 0.0, np.inf)
    choices = np.empty((intervals, count), dtype=int)
    for j in range(intervals):
        x_dot = (x[j + 1][None] - x[j][:, None]) / h  # (from, to, n)
        force = (forces[j][:, None] + forces[j + 1][None]) / 2
        flows = circuit.flows(x_dot, force)
        allowed = limits.margin(hydraulic_values(circuit, x_dot, flows)) >= -TOLERANCE
        total = np.where(allowed, cost[:, None] + h * flows.power(supply), np.inf)
        choices[j] = np.argmin(total, axis=0)
        cost = np.where(usable[j + 1], total[choices[j], np.arange(count)], np.inf)
    path = np.empty(intervals + 1, dtype=int)
    path[-1] = np.argmin(cost)
    for j in range(intervals - 1, -1, -1):
        path[j] = choices[j, path[j + 1]]
    return float(cost[path[-1]]), values[np.arange(intervals + 1), path]


def energy_optimum(
    robot: Robot,
    segment: Segment,
    supply: Supply | None = None,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    grids: tuple[int, ...] = GRIDS,
) -> EnergyOptimum:
    """The motion along ``segment`` of least pump energy under ``supply`` (default the
    machine's) over every history of the ``held`` actuator (see the module docstring), on each
    of ``grids`` (intervals) in turn. ``checked`` names the actuators whose strokes bind
    (default all).

    Each grid is solved in `PASSES` passes of `VALUES` held values per node: the first spans
    the held stroke (on the first grid) or a band around the previous grid's path, each later
    one a band `NARROWING` times as wide around the last pass's path, so that the held strokes
    end up resolved to a fraction of a millimetre at a cost of G² N per pass.
    """
    circuit = robot.circuit()
    supply = supply or circuit.supply
    row = held_indices(robot, [held])[0]
    grids = checked_grids(grids, 1)
    strokes = Limits.strokes(robot, checked)
    actuator = robot.actuators[held]
    lower, upper = actuator.lower, actuator.upper
    if not np.isfinite(upper - lower):
        raise InvalidInputError(f"the held actuator {held!r} needs a finite stroke")
    found: list[EnergyGrid] = []
    path: tuple[np.ndarray, np.ndarray] | None = None  # (t, r) of the last pass
    for intervals in grids:
        t = np.linspace(0.0, segment.duration, intervals + 1)
        tables = Tables(robot, segment, row, strokes, t)
        if path is None:
            centre, width = np.full_like(t, (lower + upper) / 2), (upper - lower) / 2
        else:
            centre, width = np.interp(t, *path), (upper - lower) / 2 * NARROWING
        for _ in range(PASSES):
            offsets = np.linspace(-width, width, SPANNING if path is None else VALUES)
            values = np.clip(centre[:, None] + offsets, lower, upper)
            energy, r = _pass(robot, supply, tables, t, values)
            if not np.isfinite(energy):
                raise InvalidInputError(
                    f"no motion along segment {segment.name} keeps every stroke and every "
                    f"limit of the hydraulic circuit with {held} within {width * 1e3:.4g} mm "
                    f"of the path searched ({intervals} intervals)"
                )
            centre, width, path = r, width * NARROWING, (t, r)
        found.append(EnergyGrid(intervals, VALUES, energy))
    return EnergyOptimum(segment, supply, held, t, r, tuple(found))
