"""The optimum of an integral objective by dynamic programming: the motion along a segment that
minimises ∫ c dt over the histories of the held actuators on a grid of their values, every
stroke and every actuator speed limit kept, and, where asked, the hydraulic circuit's limits and
actuator acceleration limits. The energy bound is this optimum with the pump energy ∫ p_P Q_P dt
as c, within the circuit's limits, as Nurmi & Mattila (Energies 10(5) 647, 2017) computed it
for a forestry crane; any objective with an integral measure, yours included, is another stage
cost of the same recursion, as in Ferrentino et al. (Robotics 10(1) 42, 2021).

- nodes t_j = j h, h = t_f / N; at each, the configurations q(r) that solve y(q) = y_d(t_j),
  x_h(q) = r (Eqs. 6, 10) are found by Newton's method (continued from node to node, seeded
  afresh where that misses) at `EXACT` held values over the stroke of one held actuator
  (r = 1), or at `EXACT_EACH` × `EXACT_EACH` over the strokes of two (r = 2); between them
  x(r), the forces at rest and q(r) are cubic splines in r (r = 1; error below 5e-5 m, largest
  at the stroke's ends) or bilinear in (r₁, r₂) (r = 2). Where the task has two solutions
  inside the joint ranges (the crane's reach alone with the fold and the telescope held: the
  lift up or down), the seeds may pick either; a cell whose corners lie on both sides of the
  fold (det [J; A_h] of both signs) would interpolate across them and is excluded, as is a held
  value whose neighbours miss the task or leave the joint ranges, or that puts a checked stroke
  past its limit. The tables hold one branch per held value and node and leave out the region
  next to the fold, so a motion that crosses the fold is not searched: an optimum whose tables
  left out a cell across it (`IntegralOptimum.folded`) may lie above a feasible motion's cost
  and is withheld as no bound (not converged; `failure` says why). With one held actuator,
  each assembly branch the improved start searches (a side of the fold: an arm's elbow up or
  elbow down, `Configurations.branches`) has tables and a recursion of its own, and the
  optimum is the least of them; for an objective's measure, each pass's states are solved
  again exactly from the interpolated configurations;
- a transition from r at t_j to r' at t_j+1 moves every actuator at ẋ = (x_j+1(r') − x_j(r))/h
  (J_H ẋ = ẏ_d to first order, Eq. 16). Its cost is the measure c at both nodes with that ẋ,
  by the trapezoidal rule, h (c_j + c_j+1)/2, or for the energy bound h p_P Q_P from the
  circuit's meter-in model against the mean of both nodes' forces at rest, A⁻ᵀ G (Eq. 23
  without velocity terms). The circuit's limits (`Limits.hydraulic`) exclude transitions, for
  the energy bound always and for an objective where a supply is given;
- actuator speed limits |ẋ| ≤ ẋ_max exclude transitions. An acceleration limit |ẍ| ≤ ẍ_max
  (|ẋ' − ẋ| / h between consecutive transitions) makes the recursion's state the transition
  into a node instead of the node (`_pass`), so that it is checked on every path, not only on
  the best path into each node as in Ferrentino et al.'s recursion: the optimum stays the
  least cost over the grid. Where the segment starts (ends) at rest, the first (last)
  transition's acceleration is checked from (to) ẋ = 0;
- the least cost to each node is the least over its predecessors; start and end are free. The
  first pass spans the strokes with `SPANNING` values per held actuator (`SPANNING_EACH` for
  r = 2), and where it finds no path, once more with values twice as fine: a held actuator
  moves by whole steps of those values, and a step per interval can be faster than its speed
  limit (the circuit's, or ``speeds``) allows, which keeps it still on that pass; each later
  one a band `NARROWING` times as wide around the last path with `VALUES` (`VALUES_EACH`)
  values (iterative dynamic programming), at a cost of G² N per pass, up to G³ N with an
  acceleration limit. On a finer grid, where the first band around the coarser
  grid's path holds no path that keeps the limits (an acceleration limit wants held values
  closer than h² ẍ_max), the band narrows around that path until one does.

Dynamic programming and not the transcription of `redundancy.planning.bound`: the load-sensing
pump pressure is a maximum over the moving cylinders and the overrunning clamp a kink, so the
cost is not differentiable where the optimum tends to lie, and the circuit's limits cut the
feasible set into pieces; the recursion finds the least cost over its grid globally. The
forces leave out inertia and velocity terms (M_H ẍ and the Coriolis part of N_H), which
would make the stage cost depend on three nodes: on the paper's crane they change
the strategies' pump energy by well under 1 % (tests/test_hydraulics.py); a ``dynamic`` measure
reads them at rest too. `IntegralOptimum.change` is the optimum's relative change from the
previous grid; where a finer grid finds no path, the coarser grid's result is kept and marked
not converged.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import cast

import numpy as np
from scipy.interpolate import CubicSpline, RegularGridInterpolator

from redundancy import _core
from redundancy.errors import InvalidInputError
from redundancy.model.hydraulics import Supply
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.ik import (
    CONTINUATION_ITERATIONS,
    FOUND,
    ITERATIONS,
    fold_side,
    held_indices,
    inverse_kinematics,
    newton,
)
from redundancy.planning.refinement import Refined, checked_grids
from redundancy.planning.starts import Configurations
from redundancy.planning.tasks import Segment
from redundancy.resolution.limits import TOLERANCE, Limits, hydraulic_values
from redundancy.resolution.objectives import Objective
from redundancy.resolution.objectives import objective as named
from redundancy.resolution.state import ActuatorSpace, evaluate, regularised

GRIDS = (50, 100)  # intervals N of the successive grids
EXACT = 81  # held values per node where the configuration is solved for, over the stroke
SPANNING = 161  # held values per node of the first pass, over the whole stroke
VALUES = 121  # held values per node of every later pass, over a narrowing band
EXACT_EACH, SPANNING_EACH, VALUES_EACH = 31, 21, 15  # the same per held actuator, for r = 2
PASSES = 10  # passes per grid, each on a narrower band around the last pass's path
NARROWING = 0.35  # each band's half-width is this fraction of the one before

# a stage cost: (node j, step h, the transitions allowed (G, G)) → the cost (G, G) of every
# transition from t_j to t_j+1 (those not allowed are excluded whatever their cost)
Stage = Callable[[int, float, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class OptimumGrid:
    """The least cost on one grid of ``intervals`` × ``values``, whether the recursion found a
    path there (``success``; why not, ``message``; the cost then nan), whether the
    acceleration limit raised the cost (``acceleration_binds``) and how many cells of the
    tables were left out for lying across the task's fold (``folded``, see `Tables`)."""

    intervals: int
    values: int
    optimum: float
    success: bool = True
    message: str = ""
    acceleration_binds: bool = False
    folded: int = 0


@dataclass(frozen=True)
class IntegralOptimum(Refined):
    """The motion of least ∫ c dt on the finest grid where the recursion found a path: node
    times t (N + 1,) s and the held values r at them, (N + 1,) for one held actuator, (N + 1, r)
    for several, every actuator's x (N + 1, n) (m, or rad for a rotary actuator) and the
    configurations q (N + 1, n) there, and every grid's least cost. ``objective`` names the
    measure c: the energy bound's is the pump energy under ``supply``, its optimum in J; an
    objective's optimum is in its measure's unit times s."""

    segment: Segment
    objective: str
    held: str | tuple[str, ...]
    t: np.ndarray
    r: np.ndarray
    x: np.ndarray
    q: np.ndarray
    grids: tuple[OptimumGrid, ...]
    supply: Supply | None = None

    @property
    def searched(self) -> OptimumGrid:
        """The finest grid where the recursion found a path: the motion's own."""
        return next(grid for grid in reversed(self.grids) if grid.success)

    @property
    def optimum(self) -> float:
        """The least cost on the finest grid where the recursion found a path."""
        return self.searched.optimum

    @property
    def acceleration_binds(self) -> bool:
        """Whether the acceleration limit raised the motion's cost (the least cost without it
        is lower)."""
        return self.searched.acceleration_binds

    @property
    def folded(self) -> int:
        """The most cells any grid's tables left out for lying across the task's fold."""
        return max(grid.folded for grid in self.grids)

    @property
    def converged(self) -> bool:
        """Converged (`Refined.converged`) on tables that left out no cell across the fold."""
        return super().converged and not self.folded

    @property
    def failure(self) -> str | None:
        """Why the optimum is no result (`Refined.failure`), or that its tables left out cells
        across the task's fold: a motion that crosses it is not searched, so the optimum may
        lie above a feasible motion's cost and is no bound."""
        if not self.folded:
            return super().failure
        return (
            f"no bound: the tables left out {self.folded} cells across the task's fold (det "
            f"[J; A_h] of both signs at their corners), so a motion that crosses it is not "
            "searched"
        )

    @property
    def energy(self) -> float:
        """The least pump energy on the finest grid, J (the energy bound)."""
        if self.supply is None:
            raise InvalidInputError(
                f"the optimum of {self.objective!r} is no energy bound: read its optimum"
            )
        return self.optimum


EnergyOptimum = IntegralOptimum  # the energy bound's result, by its earlier name


def _nodes(robot, segment, rows: list[int], values: np.ndarray, t: np.ndarray, branch=None):
    """Configurations q (N + 1, G, n) reaching y_d(t_j) with the held
    actuators ``rows`` at each of ``values`` (G, r), and where they were found (N + 1, G):
    projected Newton steps (`newton`, bounded) from the previous node's configuration; at the
    first node, by continuation along the held value on ``branch`` (the `Configurations` of
    one assembly branch, one held actuator: the branch to keep to), or from
    `inverse_kinematics`'s spread of seeds where none was found; then, where that misses, from
    the configuration found at the nearest held values of the same node. Keeping to the joint
    ranges keeps to one assembly branch: a cylinder's length is the same at q and −q. Last,
    held values a grid step beyond those found are continued from them past the joint ranges
    (unbounded), so that a cell reaches across a joint limit and a path can ride the limit
    (the tables check the joint ranges where they interpolate)."""
    held = [robot.actuators.names[row] for row in rows]
    points = segment.position(t)
    step = np.array([np.diff(np.unique(v)).min(initial=np.inf) for v in values.T])
    q = np.empty((len(t), len(values), robot.n))
    found = np.zeros((len(t), len(values)), dtype=bool)
    target = np.column_stack([np.empty((len(values), robot.m)), values])
    for j, point in enumerate(points):
        target[:, : robot.m] = point
        if j:
            q[j], residual, *_ = newton(robot, q[j - 1], rows, target, ITERATIONS, bounded=True)
            found[j] = residual < FOUND
        elif branch is not None:
            starts = branch.at(values[:, 0])
            q[j], found[j] = starts.q, starts.reachable
        if not found[j].any():
            seeded = inverse_kinematics(robot, point, held, values)
            q[j], found[j] = seeded.q, seeded.reached
        for bounded in (True, False):
            missing = np.flatnonzero(~found[j])
            if not (missing.size and found[j].any()):
                break
            known = np.flatnonzero(found[j])
            apart = np.abs(values[missing, None] - values[known])  # (missing, known, r)
            if not bounded:  # past the joint ranges: only a grid step beyond a value found
                beside = (apart <= step * (1 + 1e-9)).all(axis=2).any(axis=1)
                missing, apart = missing[beside], apart[beside]
            nearest = known[np.argmin(np.linalg.norm(apart, axis=2), axis=1)]
            q[j, missing], residual, *_ = newton(
                robot, q[j, nearest], rows, target[missing], ITERATIONS, bounded=bounded
            )
            found[j, missing] = residual < FOUND
    return q, found


class Tables:
    """Strokes x, forces F_H at rest (A⁻ᵀ G) and configurations q as functions of the held
    values r at every node: exact at the solved values (`EXACT` over one held stroke, or
    `EXACT_EACH` over each of two), cubic splines in r (r = 1) or bilinear (r = 2) between
    them. A cell of solved values (an interval, r = 1) is used only where its corners are all
    usable and on one branch: det K, K = [J; A_h] (Eqs. 7, 11), of one sign at all of them. A
    cell whose corners lie on both sides of a fold (K singular, where the task's two solutions
    meet) would interpolate across both."""

    def __init__(
        self, robot, segment, rows: list[int], strokes: Limits, t: np.ndarray, branch=None
    ):
        actuators = robot.actuators
        count = EXACT if len(rows) == 1 else EXACT_EACH
        self.axes = [np.linspace(actuators.lower[r], actuators.upper[r], count) for r in rows]
        values = np.stack(np.meshgrid(*self.axes, indexing="ij"), -1).reshape(-1, len(rows))
        q, found = _nodes(robot, segment, rows, values, t, branch)
        flat = q.reshape(-1, robot.n)
        space, bad = regularised(evaluate(robot, flat))
        usable = found.ravel() & ~bad  # the joint ranges, as the strokes, are checked at r
        self.joints = Limits.joints(robot)
        forces = np.where(usable[:, None], space.N_H, 0.0)  # A⁻ᵀ G at rest
        self.usable = usable.reshape(len(t), len(values))
        branch = fold_side(space, rows)
        grid = (len(t), *(count,) * len(rows))
        sides = [(usable & (branch == side)).reshape(grid) for side in (-1, 1)]
        self.cells = _cells(sides[0]) | _cells(sides[1])  # (N + 1, G − 1[, G − 1])
        # cells left out for lying across the fold alone: a motion through them is not searched
        self.folded = int((_cells(self.usable.reshape(grid)) & ~self.cells).sum())
        self.strokes, self.n = strokes, robot.n
        self.robot, self.rows, self.points = robot, rows, segment.position(t)
        tables = np.concatenate([space.x, forces, flat], axis=1).reshape(len(t), len(values), -1)
        if len(rows) == 1:
            self.interpolants = [
                _spline(self.axes[0], table, ok) for table, ok in zip(tables, self.usable)
            ]
        else:
            shape = (count, count, -1)
            self.interpolants = [
                RegularGridInterpolator(self.axes, table.reshape(shape)) for table in tables
            ]

    def at(self, r: np.ndarray):
        """x, F_H and q (N + 1, G, n) and where usable (N + 1, G) at held values r
        (N + 1, G, r): in a usable cell, every stroke and every joint within its limits (so
        that a path may ride a limit between two solved values, one of them past it)."""
        n = self.n
        both = np.stack([table(row) for table, row in zip(self.interpolants, r)])
        x, forces, q = both[..., :n], both[..., n : 2 * n], both[..., 2 * n :]
        # the cell the interpolation reads, as `RegularGridInterpolator` finds it
        cell = [
            np.clip(np.searchsorted(a, r[..., k]) - 1, 0, len(a) - 2)
            for k, a in enumerate(self.axes)
        ]
        usable = self.cells[(np.arange(len(r))[:, None], *cell)]
        inside = (self.strokes.margin(x) >= -TOLERANCE) & (self.joints.margin(q) >= -TOLERANCE)
        return x, forces, q, usable & inside

    def solved(self, r: np.ndarray, q: np.ndarray):
        """The states (N + 1) G, node by node, at held values r (N + 1, G, r) solved exactly by
        Newton's method from the interpolated configurations q (N + 1, G, n), at rest (ẍ = 0:
        F_H = A⁻ᵀ G), and where they were found inside the joint ranges and the strokes
        (N + 1, G)."""
        robot, (nodes, count) = self.robot, r.shape[:2]
        target = np.concatenate([np.repeat(self.points, count, 0), r.reshape(nodes * count, -1)], 1)
        flat, miss, *_ = newton(
            robot, q.reshape(-1, robot.n), self.rows, target, CONTINUATION_ITERATIONS, True
        )
        space, bad = regularised(evaluate(robot, flat))
        found = (miss < FOUND) & ~bad & (self.strokes.margin(space.x) >= -TOLERANCE)
        return replace(space, x_ddot=np.zeros_like(space.x)), found.reshape(nodes, count)


def _cells(corners: np.ndarray) -> np.ndarray:
    """Where all corners are true, (N + 1, G − 1[, G − 1]), of cells between solved held values
    marked ``corners`` (N + 1, G[, G])."""
    for axis in range(1, corners.ndim):
        corners = np.delete(corners, -1, axis) & np.delete(corners, 0, axis)
    return corners


def _spline(axis: np.ndarray, table: np.ndarray, usable: np.ndarray):
    """A cubic spline through the ``usable`` rows of ``table`` at held values ``axis``, as a
    function of held values (G, 1) (zero where fewer than two are usable)."""
    if usable.sum() < 2:
        return lambda r: np.zeros((len(r), table.shape[1]))
    spline = CubicSpline(axis[usable], table[usable], axis=0)
    return lambda r: spline(r[:, 0])


def _circuit_stage(
    robot: Robot, supply: Supply, x: np.ndarray, forces: np.ndarray, stage: Stage | None = None
) -> Stage:
    """``stage`` (by default the pump energy h p_P Q_P, J) on the transitions from t_j to t_j+1
    between the nodes' strokes x and forces at rest (N + 1, G, n) whose meter-in flows under
    ``supply`` keep the circuit's limits: each load pressure, the pump flow, each cylinder
    speed; inf on the others."""
    circuit, limits = robot.circuit(), Limits.hydraulic(robot, supply)

    def cost(j: int, h: float, allowed: np.ndarray) -> np.ndarray:
        x_dot = (x[j + 1][None] - x[j][:, None]) / h  # (from, to, n)
        flows = circuit.flows(x_dot, (forces[j][:, None] + forces[j + 1][None]) / 2)
        within = limits.margin(hydraulic_values(circuit, x_dot, flows)) >= -TOLERANCE
        if stage is None:
            return np.where(allowed & within, h * flows.power(supply), np.inf)
        return stage(j, h, allowed & within)

    return cost


def _measure_stage(objective: Objective, space: ActuatorSpace, x: np.ndarray) -> Stage:
    """The objective's measure at both ends of each transition with its ẋ, by the
    trapezoidal rule: h (c(s_j, ẋ) + c(s_j+1, ẋ)) / 2. ``space`` holds the (N + 1) G states at
    the held values, node by node; it is measured on the transitions allowed alone."""
    count = x.shape[1]

    def cost(j: int, h: float, allowed: np.ndarray) -> np.ndarray:
        start, end = np.nonzero(allowed)
        x_dot = (x[j + 1][end] - x[j][start]) / h
        ends = (space.take(j * count + start), space.take((j + 1) * count + end))
        found = np.full(allowed.shape, np.inf)
        found[start, end] = h / 2 * sum(objective.measure(s, x_dot) for s in ends)
        return found

    return cost


def _pass(
    x: np.ndarray,
    usable: np.ndarray,
    stage: Stage,
    t: np.ndarray,
    speeds: np.ndarray,
    accelerations: np.ndarray,
    rest: tuple[bool, bool] = (False, False),
):
    """Dynamic programming over the nodes' strokes x (N + 1, G, n) at times t: the least cost
    (inf where no path keeps the limits), the index of its held values at each node (N + 1,),
    and the least cost without the acceleration limit (the same where it does not bind).

    Without the acceleration limit the recursion's state is the node: V_j+1(d) = min over c of
    V_j(c) + C_j(c, d), G² per interval, C_j the stage cost (inf where a transition is not
    allowed). With it the state is the transition into the node, so that every acceleration of
    every path is checked: V_j+1(c, d) = C_j(c, d) + the least V_j(b, c) over the b with
    |ẋ_j(c, d) − ẋ_j−1(b, c)| ≤ h ẍ_max in every limited actuator (`_core.accelerated_step`,
    up to G³ per interval), the least cost over the grid. Where ``rest`` (at the start, at the
    end), the first (last) transition's acceleration is checked from (to) ẋ = 0."""
    intervals, count = len(t) - 1, x.shape[1]
    h, fast, quick = t[1], np.isfinite(speeds), np.isfinite(accelerations)  # the limited ones
    reach = h * (accelerations[quick] + TOLERANCE)  # the largest change of ẋ in one step

    def steady(rate: np.ndarray) -> np.ndarray:  # the transitions (c, d) that start or end at rest
        return np.all(np.abs(rate) <= reach, axis=-1)

    free = np.where(usable[0], 0.0, np.inf)  # V_j over the nodes, no acceleration limit
    choices = np.empty((intervals, count), dtype=int)  # each node's best predecessor
    if quick.any():  # V_j over the transitions into node j, their rates, their best predecessors
        pairs, incoming = np.empty((count, count)), np.empty((count, count, quick.sum()))
        before = np.empty((intervals, count, count), dtype=np.int32)
    for j in range(intervals):
        x_dot = (x[j + 1][None] - x[j][:, None]) / h  # (from, to, n)
        allowed = np.all(np.abs(x_dot[..., fast]) <= speeds[fast] + TOLERANCE, axis=2)
        steps = stage(j, h, allowed & usable[j + 1] & np.isfinite(free)[:, None])
        total = free[:, None] + steps
        choices[j] = np.argmin(total, axis=0)
        free = total[choices[j], np.arange(count)]
        if quick.any():
            rate = x_dot[..., quick]
            if j:
                best, before[j] = _core.accelerated_step(pairs, incoming, rate, reach)
                pairs = steps + best
            else:
                pairs = np.where(steady(rate) | (not rest[0]), steps, np.inf)
            incoming = rate
    if not quick.any():
        last = int(np.argmin(free))
        path = [last]
        for j in range(intervals - 1, -1, -1):
            path.append(choices[j, path[-1]])
        return float(free[last]), np.array(path[::-1]), float(free[last])
    if rest[1]:
        pairs = np.where(steady(incoming), pairs, np.inf)
    c, d = (int(i) for i in np.unravel_index(np.argmin(pairs), pairs.shape))
    path = [d, c]
    for j in range(intervals - 1, 0, -1):
        path.append(before[j, path[-1], path[-2]])
    return float(pairs[c, d]), np.array(path[::-1]), float(free.min())


def _limit(robot: Robot, value, what: str) -> np.ndarray:
    """A per-actuator limit (n,) from one number or n (default none), checked."""
    given = np.inf if value is None else value
    try:
        limit = np.broadcast_to(np.asarray(given, dtype=float), (robot.n,))
    except (TypeError, ValueError):
        limit = np.full(robot.n, np.nan)
    if not np.all(limit > 0):
        raise InvalidInputError(
            f"{what} must be one number > 0 or {robot.n} (one per actuator: "
            f"{', '.join(robot.actuators.names)}); got {value!r}"
        )
    return limit


# builds a pass's stage from the tables and its held values r (N + 1, G, r): the strokes x and
# configurations q (N + 1, G, n) and where usable (N + 1, G), as the stage reads them, and the
# stage cost
Builder = Callable[[Tables, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, Stage]]


Path = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[OptimumGrid, ...]]


def _optimum(
    robot: Robot,
    segment: Segment,
    held: str | Sequence[str],
    checked: tuple[str, ...] | None,
    grids: tuple[int, ...],
    build: Builder,
    speeds: np.ndarray,
    accelerations: np.ndarray,
    near: np.ndarray | None = None,
) -> Path:
    """Iterative dynamic programming over the ``held`` actuators' values with the stage costs
    ``build`` makes (see the module docstring), on each of ``grids`` in turn: the node times t
    (N + 1,), the held values (N + 1, r), strokes x and configurations q (N + 1, n) on the path
    of the finest grid where the recursion found one, and every grid's least cost (a grid
    without a path after one with a path ends the refinement, marked failed). With one held
    actuator, the configurations keep to the assembly branch of ``near`` where it is given,
    else the optimum is the least over every branch the improved start searches
    (`Configurations.branches`), each on the finest grid where it found a path: a motion
    cannot pass from one elbow to the other inside the joint ranges, so each is a recursion of
    its own."""
    rows = held_indices(robot, held)
    names = [robot.actuators.names[row] for row in rows]
    if len(rows) > 2:
        raise InvalidInputError(
            f"dynamic programming over the held actuators holds one or two; {robot.name} "
            f"has {len(rows)} redundant degrees ({', '.join(names)})"
        )
    grids = checked_grids(grids, 1)
    on_branch = partial(
        _on_branch, robot, segment, rows, checked, grids, build, speeds, accelerations
    )
    if len(rows) == 2:
        return on_branch(None)
    if near is not None:
        return on_branch(Configurations.near(robot, segment, names[0], near))
    found: list[Path] = []
    failure: InvalidInputError | None = None
    for branch in Configurations.branches(robot, segment, names[0]):
        try:
            found.append(on_branch(branch))
        except InvalidInputError as error:  # no path on this branch: the others may have one
            failure = failure or error
    if not found:
        raise cast(InvalidInputError, failure)
    return min(found, key=lambda path: next(g.optimum for g in reversed(path[-1]) if g.success))


def _on_branch(
    robot: Robot,
    segment: Segment,
    rows: list[int],
    checked: tuple[str, ...] | None,
    grids: tuple[int, ...],
    build: Builder,
    speeds: np.ndarray,
    accelerations: np.ndarray,
    branch: Configurations | None,
) -> Path:
    """`_optimum` on one assembly ``branch`` (one held actuator; None: the configurations
    inverse kinematics picks), the held actuators' ``rows`` and the ``grids`` checked."""
    names = [robot.actuators.names[row] for row in rows]
    strokes = Limits.strokes(robot, checked)
    lower, upper = robot.actuators.lower[rows], robot.actuators.upper[rows]
    if not np.all(np.isfinite(upper - lower)):
        raise InvalidInputError(f"the held actuators {names} need finite strokes")
    counts = (SPANNING, VALUES) if len(rows) == 1 else (SPANNING_EACH, VALUES_EACH)
    last = counts[1] ** len(rows)  # held values per node of every grid's last pass
    start, end = segment.velocity_at(np.array([0.0, segment.duration]))
    rest = (not np.any(start), not np.any(end))  # the task at rest there
    found: list[OptimumGrid] = []
    path: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # t, r, x, q
    for intervals in grids:
        t = np.linspace(0.0, segment.duration, intervals + 1)
        tables = Tables(robot, segment, rows, strokes, t, branch)
        if path is None:
            centre, width = np.tile((lower + upper) / 2, (len(t), 1)), (upper - lower) / 2
        else:
            centre = np.column_stack([np.interp(t, path[0], r) for r in path[1].T])
            width = (upper - lower) / 2 * NARROWING
        reached = False  # whether a pass on this grid found a path
        widest, without_limit = width, False  # the first band; whether a pass found a path
        spanning = counts[0]
        for done in range(PASSES):
            first = path is None and not reached  # a pass over the whole strokes
            each = spanning if first else counts[1]
            axes = [np.linspace(-w, w, each) for w in width]
            offsets = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(rows))
            values = np.clip(centre[:, None] + offsets, lower, upper)
            x, q, usable, stage = build(tables, values)
            optimum, index, free = _pass(x, usable, stage, t, speeds, accelerations, rest)
            without_limit |= bool(np.isfinite(free))  # without the acceleration limit
            if not np.isfinite(optimum):
                if first and spanning == counts[0]:  # once more, on values twice as fine
                    spanning = 2 * spanning - 1
                    continue
                if path is not None and not reached and done < PASSES - 1:
                    width = width * NARROWING  # finer values about the coarser grid's path
                    continue
                units = (robot.actuators.maps[row].unit for row in rows)
                searched = width if reached else widest  # the widest band it searched
                band = " × ".join(f"{w:.4g} {unit}" for w, unit in zip(searched, units))
                message = (
                    f"dynamic programming found no motion along segment {segment.name} that "
                    f"keeps every stroke and every limit with {', '.join(names)} within {band} "
                    f"of the path searched ({intervals} intervals)"
                )
                if without_limit:  # the limit wants held values closer than h² ẍ_max
                    message += (
                        "; without the acceleration limit one would: the limit is too tight for "
                        "the task, or the held values lie too far apart for it on this grid "
                        "(begin with a coarser one)"
                    )
                if path is None:
                    raise InvalidInputError(message)
                found.append(
                    OptimumGrid(intervals, last, np.nan, False, message, False, tables.folded)
                )
                return *path, tuple(found)
            nodes, reached = np.arange(len(t)), True
            r, x, q = values[nodes, index], x[nodes, index], q[nodes, index]
            centre, width = r, width * NARROWING
        path = (t, r, x, q)
        found.append(OptimumGrid(intervals, last, optimum, True, "", free < optimum, tables.folded))
    assert path is not None  # checked_grids gives one grid at least
    return *path, tuple(found)


def integral_optimum(
    robot: Robot,
    segment: Segment,
    objective: str | Objective,
    held: str | Sequence[str],
    checked: tuple[str, ...] | None = None,
    grids: tuple[int, ...] = GRIDS,
    speeds=None,
    accelerations=None,
    supply: Supply | None = None,
    near: np.ndarray | None = None,
) -> IntegralOptimum:
    """The motion along ``segment`` of least ∫ c dt, c the measure of ``objective`` (one with
    an integral measure, yours included), over the histories of the ``held`` actuators (one or
    two; see the module docstring), on each of ``grids`` (intervals) in turn. ``checked``
    names the actuators whose strokes bind (default all); ``speeds`` and ``accelerations``
    limit every actuator's |ẋ| and |ẍ| (one number, or one per actuator; m/s and m/s², rad/s
    and rad/s² for a rotary one; default none); a ``supply`` of the robot's circuit keeps the
    circuit's limits under it (default none kept). With one held actuator, ``near``, a
    configuration (n,) at the segment's start, names the assembly branch to keep to (the
    improved start's, `SearchResult.start_configuration`); by default the optimum is the least
    over every branch the improved start searches."""
    require_robot(robot)
    objective = named(objective)
    if objective.reduction != "integral":
        raise InvalidInputError(
            f"objective {objective.name!r} is reduced to its {objective.reduction}; the "
            "integral optimum needs an integral one (global_optimum bounds a peak)"
        )

    def build(tables: Tables, values: np.ndarray):
        x, _, q, usable = tables.at(values)
        space, found = tables.solved(values, q)
        x, q = space.x.reshape(x.shape), space.q.reshape(q.shape)
        stage = _measure_stage(objective, space, x)
        if supply is not None:
            stage = _circuit_stage(robot, supply, x, space.N_H.reshape(x.shape), stage)
        return x, q, usable & found, stage

    limits = _limit(robot, speeds, "speeds"), _limit(robot, accelerations, "accelerations")
    found = _optimum(robot, segment, held, checked, grids, build, *limits, near)
    return _result(robot, segment, objective.name, held, *found)


def _result(robot, segment, name, held, t, r, x, q, grids, supply=None) -> IntegralOptimum:
    """The optimum with one held actuator's values as (N + 1,), several as (N + 1, r)."""
    names = tuple(robot.actuators.names[row] for row in held_indices(robot, held))
    if len(names) == 1:
        return IntegralOptimum(segment, name, names[0], t, r[:, 0], x, q, grids, supply)
    return IntegralOptimum(segment, name, names, t, r, x, q, grids, supply)


def energy_optimum(
    robot: Robot,
    segment: Segment,
    supply: Supply | None,
    held: str | Sequence[str],
    checked: tuple[str, ...] | None = None,
    grids: tuple[int, ...] = GRIDS,
) -> IntegralOptimum:
    """The energy bound: the motion along ``segment`` of least pump energy under ``supply``
    (None: the machine's) over every history of the ``held`` actuators (one or two), every
    stroke and every limit of the hydraulic circuit kept (see the module docstring), on each of
    ``grids`` (intervals) in turn; with one held actuator, the least over every assembly branch
    the improved start searches, so that it bounds a strategy on any of them. ``checked`` names
    the actuators whose strokes bind (default all)."""
    require_robot(robot)
    supply = supply or robot.circuit().supply

    def build(tables: Tables, values: np.ndarray):
        x, forces, q, usable = tables.at(values)
        return x, q, usable, _circuit_stage(robot, supply, x, forces)

    free = np.full(robot.n, np.inf)
    found = _optimum(robot, segment, held, checked, grids, build, free, free)
    return _result(robot, segment, f"{supply.name} pump energy", held, *found, supply=supply)
