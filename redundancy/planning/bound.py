"""The bound: the motion along a segment whose whole history of the held actuator is optimised.

The paper's improved method chooses only where the motion starts; here the held stroke r(t) is
free at every instant, and the motion that tracks the task exactly, keeps every checked stroke
and has the least peak of the objective is found by direct transcription:

- unknowns: r_j = x_h(t_j) at N + 1 nodes t_j = j h, h = t_f / N, and the peak s;
- at each node q_j solves y(q_j) = y_d(t_j), x_h(q_j) = r_j (Eqs. 6, 10) by Newton's method
  from the previous iterate: the task is tracked exactly at every node;
- the held rates ṙ = D r (second-order backward differences, `backward_differentiation`) fix
  the velocities: K_j q̇_j = [ẏ_d; ṙ_j] with K = [J; A_h] (Eqs. 7, 11) and ẋ_j = A_j q̇_j, so
  that J_H ẋ_j = ẏ_d (Eq. 16); node j takes the objective's measure of its state and ẋ_j
  (ẋᵀẋ, ẋᵀ M_H ẋ, or a user's own). Central differences would not do: blind to a history
  alternating node by node, r_j + (−1)ʲ c, they let the solver place every node's
  configuration freely at rates no motion through those strokes has. Backward differences see
  every stroke they difference: only a constant has no rate;
- minimise σ = s / s₀ (the peak against the starting history's, so that the problem is the
  same whatever the objective's unit) with a tie-break `SMOOTHING` on mean ṙ² against that
  history's peak ẋᵀẋ, subject to σ ≥ the measure / s₀ and lower ≤ x(q_j) ≤ upper for every
  checked actuator at every node (the held one through the bounds on r).

Gradients: ∂q_j/∂r_j = K_j⁻¹ e and ∂x_j/∂r_j = A_j ∂q_j/∂r_j; the measure's derivative through
ṙ_j is a central difference along ∂ẋ_j/∂ṙ_j = A_j K_j⁻¹ e (exact for a quadratic measure), and
through q_j at fixed ṙ_j a central difference along ∂q_j/∂r_j. SciPy's SLSQP solves the problem
on a sequence of grids: the first from several pseudoinverse motions (the problem is not
convex), each later one from the previous optimum. Where the solver ends above the history it
started from, or where the task is out of reach, that history stays, and the grid counts as
failed. The optimum converges at second order in h; `GlobalOptimum.change` says how much the
last refinement moved it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple, cast

import numpy as np
from scipy.linalg import block_diag
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from redundancy.errors import InvalidInputError, UnreachableError
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.ik import (
    CONTINUATION_ITERATIONS,
    FOUND,
    held_indices,
    inverse_kinematics,
    named_values,
    newton,
)
from redundancy.planning.integrate import Trajectory
from redundancy.planning.motions import simulate_path
from redundancy.planning.refinement import Refined, checked_grids
from redundancy.planning.starts import (
    Configurations,
    SearchResult,
    chosen_held,
    improved_start,
)
from redundancy.planning.tasks import Chain, Segment, checked_path
from redundancy.resolution.limits import Limits, amount
from redundancy.resolution.objectives import VELOCITY, Objective
from redundancy.resolution.objectives import objective as as_objective
from redundancy.resolution.state import ActuatorSpace, evaluate

GRIDS = (24, 48)  # intervals of the successive grids
MIN_INTERVALS = 4  # per segment of a chain, on every grid
MAX_INTERVALS = 192  # by default, grids twice as fine follow GRIDS until the optimum converges,
# up to this many intervals
CANDIDATES = 3  # starts over the reachable range the first grid is also solved from
ITERATIONS = 400  # SLSQP iterations per grid, at most
FUNCTION_TOLERANCE = 1e-7  # SLSQP's ftol on the scaled peak
POLISH_TOLERANCE = 1e-10  # its ftol polishing the peak alone, near the optimum: brings the
# peak to 1e-10 of the least (1e-7 left it 1.6e-9 above a start that is itself the optimum)
LIMIT_MARGIN = 1e-6  # m: the strokes are kept this far inside their limits, so that solver
# round-off never puts a node outside them
SMOOTHING = 1e-4  # weight of mean ṙ² against the peak ẋᵀẋ: picks one optimum where many share
# the peak, and moves the peak by less than this fraction
ABOVE = 1e-4  # a bound above the improved start's peak by more than this fraction is withheld:
# below it, the improved motion's 10 ms grid and the bound's nodes sample a peak every history
# shares (the slewing crane's lift-swing, 1e-5)
DIFFERENCE_STEP = 1e-6  # m (and m/s): step of the central differences through q and ṙ
UNREACHED = 1e3  # the measure at a node Newton's method does not reach, in starting peaks: a
# trial step of the solver into strokes the task cannot be tracked with is a step it backs out of


@dataclass(frozen=True)
class GridSolution:
    """The optimum on one grid: its ``intervals``, the optimal ``peak`` (m²/s² or J), and the
    solver's report (``success``, ``iterations``, ``message``), with the largest constraint
    violation at its solution (``violation``: a fraction of the starting peak for the peak's
    constraints, of the stroke for the strokes')."""

    intervals: int
    peak: float
    success: bool
    iterations: int
    message: str
    violation: float

    @property
    def optimum(self) -> float:
        """The optimal peak: what `Refined` judges the grid's convergence by."""
        return self.peak


@dataclass(frozen=True)
class Grids(Refined):
    """Grid solutions alone, judged for their convergence."""

    grids: tuple[GridSolution, ...]


@dataclass(frozen=True)
class GlobalOptimum(Refined):
    """The optimised motion on the finest grid and every grid's solution.

    ``motion`` holds the nodes of the finest grid: q, x and y (= y_d to Newton's tolerance),
    and ẋ from the transcribed held rates, so that its peak of the objective is the optimum;
    its ``resolver`` is the objective's law, whose measure the motion minimises. It is the
    optimum at its nodes, not a plan to run: its held history interpolated between them, with
    the task solved exactly, peaks higher (a few per cent) and may pass a stroke by a hair.
    ``held`` names the held actuator (the names, with several), ``start`` its stroke at t = 0
    (m or rad; the strokes, with several).
    """

    segment: Segment | Chain
    objective: Objective
    held: str | tuple[str, ...]
    motion: Trajectory
    start: float | tuple[float, ...]
    grids: tuple[GridSolution, ...]

    @property
    def bound(self) -> float:
        """The optimal peak on the finest grid: the bound on every start's peak where the
        optimum `converged`; otherwise no bound, and `failure` says why: the finest grid's
        solution, where the solver failed, may peak above the motion it started from, even
        above the improved start's peak."""
        return self.optimum

    def withheld(self, peak: float | None) -> str | None:
        """Why the bound is no result against the improved start's ``peak`` (its motion's, on
        the grid), in one line, or None: it did not converge (`failure`), or it lies above that
        peak by more than `ABOVE`, which a bound cannot (the solver stopped at a local
        optimum)."""
        if self.failure is None and peak is not None and self.bound > peak * (1 + ABOVE):
            return (
                f"the solver's optimum {self.bound:.5g} lies above the improved start's peak "
                f"{peak:.5g}: a local optimum, not the least"
            )
        return self.failure


def backward_differentiation(intervals: int, h: float) -> np.ndarray:
    """The (N + 1, N + 1) matrix D with ṙ ≈ D r on a uniform grid of step h, second order:
    ṙ_j ≈ (3 r_j − 4 r_(j−1) + r_(j−2)) / 2h from node 2 on, the same stencil forward at nodes 0
    and 1. Its symbol (1 − e^(−iθ))(3 − e^(−iθ)) / 2h vanishes at θ = 0 alone: no history but a
    constant has zero rates (the alternation included, at rate 4c/h)."""
    D = np.zeros((intervals + 1, intervals + 1))
    later = np.arange(2, intervals + 1)
    D[later, later - 2], D[later, later - 1], D[later, later] = 0.5, -2.0, 1.5
    D[0, :3] = D[1, 1:4] = [-1.5, 2.0, -0.5]
    return D / h


def differentiation(intervals: int, h: float) -> np.ndarray:
    """The (N + 1, N + 1) matrix D with ṙ ≈ D r on a uniform grid of step h: central
    differences inside, second-order one-sided ones at both ends. Blind to a history that
    alternates node by node (see the module docstring): the periodic transcription
    (`redundancy.planning.cycles`) that differences with it filters that alternation out."""
    D = np.zeros((intervals + 1, intervals + 1))
    inside = np.arange(1, intervals)
    D[inside, inside - 1], D[inside, inside + 1] = -0.5, 0.5
    D[0, :3] = [-1.5, 2.0, -0.5]
    D[-1, -3:] = [0.5, -2.0, 1.5]
    return D / h


def node_intervals(path: Segment | Chain, intervals: int) -> list[int]:
    """``intervals`` shared among the path's segments by duration, at least `MIN_INTERVALS`
    each (a segment's own count)."""
    if isinstance(path, Segment):
        return [intervals]
    durations = np.array([s.duration for s in path.segments])
    return [max(MIN_INTERVALS, round(intervals * d / durations.sum())) for d in durations]


def node_times(path: Segment | Chain, intervals: int) -> np.ndarray:
    """The times of the transcription's nodes along ``path`` (N,), s: each segment's uniform
    grid of its `node_intervals`, a corner's time twice (the end of one, the start of the
    next)."""
    segments = path.segments if isinstance(path, Chain) else (path,)
    offsets = np.cumsum([0.0] + [s.duration for s in segments])
    return np.concatenate(
        [
            np.linspace(0.0, s.duration, count + 1) + offset
            for s, count, offset in zip(segments, node_intervals(path, intervals), offsets)
        ]
    )


class Transcription:
    """The problem on one grid of ``intervals`` along ``path`` (a segment, or a chain of them
    such as a work cycle): the constraints and their Jacobian with respect to z = (r, σ), the
    held strokes r at the nodes ((U, r) for r held actuators, flattened row by row) and
    σ = s / s₀ the peak against the starting history's, for SLSQP.

    Each segment has the nodes of its share of ``intervals`` (`node_intervals`); a corner's two
    nodes (the end of one segment, the start of the next) share one unknown, and ``periodic``
    ties the last node to the first, r(T) = r(0). Held rates are differences within each
    segment (by default `backward_differentiation`), one-sided at its ends, so that they may
    jump at a corner, as ẏ does at constant speed. ``objective`` gives the measure, ``rows``
    the held actuators (one row, or several), ``limits`` the other checked actuators' strokes,
    kept ``margin`` inside at the nodes (an unbounded end is no constraint); ``guess`` (N, n)
    the configurations Newton's method starts from at the nodes (`node_times`).
    ``smoothness`` weighs a second tie-break, mean r̈² inside each segment.
    """

    def __init__(
        self,
        robot: Robot,
        objective: Objective,
        path: Segment | Chain,
        rows: int | Sequence[int],
        limits: Limits,
        intervals: int,
        guess: np.ndarray,
        periodic: bool = False,
        margin: float = LIMIT_MARGIN,
        smoothness: float = 0.0,
        differences: Callable[[int, float], np.ndarray] = backward_differentiation,
    ):
        self.robot, self.objective, self.smoothness = robot, objective, smoothness
        self.rows = [int(rows)] if isinstance(rows, int | np.integer) else list(rows)
        self.columns = limits.columns
        segments = path.segments if isinstance(path, Chain) else (path,)
        counts = node_intervals(path, intervals)
        self.piece = np.repeat(np.arange(len(segments)), [c + 1 for c in counts])  # segments
        self.t = node_times(path, intervals)
        self.local = self.t - np.cumsum([0.0] + [s.duration for s in segments])[self.piece]
        local = [self.local[self.piece == i] for i in range(len(segments))]
        self.points = np.concatenate([s.position(t) for s, t in zip(segments, local)])
        self.y_dot = np.concatenate([s.velocity_at(t) for s, t in zip(segments, local)])
        self.owner = np.arange(len(self.t)) - self.piece  # each node's unknown, one per corner
        if periodic:
            self.owner[-1] = 0
        self.incidence = np.eye(self.owner.max() + 1)[self.owner]  # (nodes, unknowns)
        steps = [t[1] for t in local]
        self.D = block_diag(*map(differences, counts, steps)) @ self.incidence
        # the second differences of the held strokes inside each segment, per s²
        second = [np.diff(np.eye(c + 1), 2, axis=0) / h**2 for c, h in zip(counts, steps)]
        self.S = block_diag(*second) @ self.incidence
        self.q = np.array(guess, dtype=float)
        self.space: ActuatorSpace | None = None  # the states at q, once evaluated
        self.around: tuple[np.ndarray, list[ActuatorSpace]] | None = None  # `shifted`
        lower, upper = limits.lower + margin, limits.upper - margin
        # each finite end of a stroke is a constraint, a fraction of the stroke (of 1 m or rad
        # where the stroke has an open end); an unbounded end is none
        self.span = np.where(np.isfinite(upper - lower), upper - lower, 1.0)
        self.ends = [(np.flatnonzero(np.isfinite(e)), e, s) for e, s in ((lower, 1), (upper, -1))]
        self.cache: tuple[bytes, Nodes] | None = None
        self.scale = 1.0  # s₀: the starting history's peak, in the objective's unit
        self.speed = 1.0  # its peak ẋᵀẋ, m²/s² (rad²/s² for rotary actuators)
        self.tie_break = True  # whether the cost has the tie-breaks, or is the peak alone

    def unknown_times(self) -> np.ndarray:
        """The time of each unknown node (its first node), (U,), s."""
        return self.t[np.unique(self.owner, return_index=True)[1]]

    def held(self, z: np.ndarray) -> np.ndarray:
        """The held strokes (U, r) of the unknowns z = (r, σ) or r alone."""
        return z[: self.D.shape[1] * len(self.rows)].reshape(-1, len(self.rows))

    def reach(
        self, r: np.ndarray, start: ActuatorSpace | None = None
    ) -> tuple[ActuatorSpace, np.ndarray]:
        """The states at every node for the held strokes r (U, r), Newton-continued from
        ``start`` (a solution's nodes) or else the last ones that reached every node (evaluated
        already), and which nodes it did not reach."""
        target = np.concatenate([self.points, r[self.owner]], axis=1)
        if self.space is None:
            self.space = evaluate(self.robot, self.q)
        start = self.space if start is None else start
        solved = newton(
            self.robot, start.q, self.rows, target, CONTINUATION_ITERATIONS, start=start
        )
        space = cast(ActuatorSpace, solved.space)  # given the states it starts from, Newton's
        missed = solved.miss > FOUND
        if not missed.any():
            self.q, self.space = space.q, space
        return space, missed

    def unreached(self, r: np.ndarray, missed: np.ndarray) -> InvalidInputError:
        """The error for held strokes r (U, r) whose ``missed`` nodes no configuration
        reaches."""
        first = int(np.flatnonzero(missed)[0])
        held = [self.robot.actuators.maps[row] for row in self.rows]
        strokes = ", ".join(
            f"{a.name} = {amount(v, a.unit)}" for a, v in zip(held, r[self.owner[first]])
        )
        return InvalidInputError(
            f"no configuration reaches the task at t = {self.t[first]:.3f} s with {strokes}"
        )

    def configurations(self, r: np.ndarray, start: ActuatorSpace | None = None) -> np.ndarray:
        """q at every node for the held strokes r, from ``start`` (see `reach`), or an error
        where a node is not reached."""
        space, missed = self.reach(r, start)
        if missed.any():
            raise self.unreached(r, missed)
        return space.q

    def motion(self, space: ActuatorSpace, r_dot: np.ndarray):
        """At the nodes' states with held rates ṙ (N + 1, r): K = [J; A_h] (Eqs. 7, 11),
        ẋ = A q̇ (N + 1, n) with K q̇ = [ẏ_d; ṙ], and the measure."""
        K = np.concatenate([space.J, space.A[:, self.rows]], axis=1)
        rhs = np.concatenate([self.y_dot, r_dot], axis=1)
        x_dot = (space.A @ np.linalg.solve(K, rhs[..., None]))[..., 0]
        return K, x_dot, self.objective.measure(space, x_dot)

    def evaluate(self, z: np.ndarray) -> Nodes:
        """The transcription at z = (r, σ), computed once per held history r (σ enters no
        node)."""
        key = z[:-1].tobytes()
        if self.cache is not None and self.cache[0] == key:
            return self.cache[1]
        r = self.held(z)
        r_dot = self.D @ r
        space, missed = self.reach(r)
        K, x_dot, measure = self.motion(space, r_dot)
        measure = np.where(missed, UNREACHED * self.scale, measure)
        held = len(self.rows)
        unit = np.zeros((len(space.q), self.robot.n, held))
        unit[:, self.robot.m :] = np.eye(held)
        dq = np.linalg.solve(K, unit)  # ∂q_j/∂r_jk = K⁻¹ e_k, and ∂q̇_j/∂ṙ_jk (N + 1, n, r)
        dx = space.A @ dq  # ∂x_j/∂r_jk, and ∂ẋ_j/∂ṙ_jk (N + 1, n, r)
        step = DIFFERENCE_STEP * np.moveaxis(dx, -1, 0)  # (r, N + 1, n)
        measured = [self.objective.measure(space, x_dot + s) for s in (*step, *-step)]
        measured += [self.motion(s, r_dot)[-1] for s in self.shifted(space.q, dq)]
        ahead, behind = np.reshape(measured, (2, 2, held, -1)).swapaxes(0, 1)
        # ∂ measure_j / ∂ṙ_jk along ∂ẋ_j/∂ṙ_jk, and ∂ measure_j / ∂r_jk through q_j at fixed ṙ_j
        rate, own = np.swapaxes(ahead - behind, 1, 2) / (2 * DIFFERENCE_STEP)  # (N + 1, r) each
        gradient = rate[:, None] * self.D[..., None] + own[:, None] * self.incidence[..., None]
        nodes = Nodes(measure, gradient.reshape(len(space.q), -1), space, x_dot, dx, missed)
        self.cache = (key, nodes)
        return nodes

    def continued(self, z: np.ndarray) -> Nodes:
        """The transcription at z, where Newton's method misses a node from its guess (a guess
        interpolated from a coarser grid, far between its nodes) started again from the
        configuration of its nearest reached node, pass after pass while that reaches more."""
        nodes = self.evaluate(z)
        while nodes.missed.any() and not nodes.missed.all():
            reached, missed = np.flatnonzero(~nodes.missed), np.flatnonzero(nodes.missed)
            nearest = reached[np.abs(missed[:, None] - reached[None]).argmin(axis=1)]
            self.q = nodes.space.q.copy()
            self.q[missed] = nodes.space.q[nearest]
            self.space = self.cache = None
            again = self.evaluate(z)
            if again.missed.sum() >= nodes.missed.sum():
                break
            nodes = again
        return nodes

    def shifted(self, q: np.ndarray, dq: np.ndarray) -> list[ActuatorSpace]:
        """The states at q + `DIFFERENCE_STEP` dq_k for each held k, then at q − that step,
        (N + 1, n) each, dq (N + 1, n, r) = ∂q/∂r a function of q: a node whose q the last
        iterate had too keeps its states from there."""
        fresh = np.ones(len(q), dtype=bool)
        if self.around is not None:
            fresh = ~np.all(self.around[0] == q, axis=1)
        step = DIFFERENCE_STEP * np.moveaxis(dq[fresh], -1, 0)  # (r, fresh, n)
        found = [evaluate(self.robot, q[fresh] + shift) for shift in (*step, *-step)]
        if self.around is not None and not fresh.all():
            index = np.arange(len(q))  # a kept node's among the last iterate's, at its own row
            index[fresh] = len(q) + np.arange(fresh.sum())
            found = [
                ActuatorSpace.joined([last, new]).take(index)
                for last, new in zip(self.around[1], found)
            ]
        self.around = (q, found)
        return found

    def cost(self, z):
        """σ + ε mean ṙ² / (ẋᵀẋ)₀ + ε₂ mean r̈² / (ẋᵀẋ)₀ and its gradient: the peak σ = s / s₀,
        with tie-breaks (ε = `SMOOTHING`, ε₂ = ``smoothness`` in s²) for the smoothest held
        history where many share the least peak."""
        r = self.held(z)
        r_dot, r_ddot = self.D @ r, self.S @ r
        weight = SMOOTHING / (len(r_dot) * self.speed) if self.tie_break else 0.0
        second = self.smoothness / (max(len(r_ddot), 1) * self.speed) if self.tie_break else 0.0
        gradient = 2 * weight * (self.D.T @ r_dot) + 2 * second * (self.S.T @ r_ddot)
        value = z[-1] + weight * (r_dot**2).sum() + second * (r_ddot**2).sum()
        return value, np.append(gradient.ravel(), 1.0)

    def constraints(self, z):
        return self.slack(z, self.evaluate(z))

    def slack(self, z: np.ndarray, nodes: Nodes) -> np.ndarray:
        """The constraints ≥ 0 at z, its ``nodes`` known: σ above each node's measure / s₀, and
        the strokes' `margins`."""
        return np.concatenate([z[-1] - nodes.measure / self.scale, self.margins(nodes)])

    def margins(self, nodes: Nodes) -> np.ndarray:
        """Each node's distance inside each checked finite stroke end of the actuators not held,
        a fraction of the stroke."""
        strokes = nodes.space.x[:, self.columns]
        return np.concatenate(
            [
                (sign * (strokes[:, kept] - end[kept]) / self.span[kept]).ravel()
                for kept, end, sign in self.ends
            ]
        )

    def jacobian(self, z):
        nodes = self.evaluate(z)
        count, unknowns = nodes.gradient.shape
        peak = np.concatenate([-nodes.gradient / self.scale, np.ones((count, 1))], axis=1)
        d_strokes = nodes.dx[:, self.columns] / self.span[:, None]  # (N + 1, c, r)
        blocks = [peak]
        for kept, _, sign in self.ends:
            block = np.zeros((count, len(kept), self.D.shape[1], len(self.rows)))
            block[np.arange(count), :, self.owner] = sign * d_strokes[:, kept]
            block = block.reshape(count * len(kept), unknowns)
            blocks.append(np.concatenate([block, np.zeros((len(block), 1))], axis=1))
        return np.concatenate(blocks)


class Nodes(NamedTuple):
    """The transcription at one iterate: the measure at each node (N + 1,), its gradient with
    respect to the unknowns r (N + 1, U r), the actuator space, ẋ (N + 1, n),
    ∂x_j/∂r_jk (N + 1, n, r) and the nodes Newton's method did not reach (N + 1,), whose
    measure is `UNREACHED` starting peaks."""

    measure: np.ndarray
    gradient: np.ndarray
    space: ActuatorSpace
    x_dot: np.ndarray
    dx: np.ndarray
    missed: np.ndarray


def solve_transcription(
    problem: Transcription, r0: np.ndarray, box: list, intervals: int, polish: bool = False
):
    """SLSQP from r0 (U, r) within ``box``, each held actuator's (lower, upper) (None where
    open): the grid's solution (U, r) and the transcription at it. Both r0 and the solution
    must reach the task at every node; the solver's trial steps need not. With ``polish`` the
    solution is solved again for the peak alone, from there: where the tie-break traded a hair
    of a binding peak for smoothness (1e-9 of it), the peak is the least, and the history stays
    where the peak does not bind (nothing pulls it there)."""
    start = problem.continued(np.append(r0, 0.0))
    if start.missed.any():
        raise problem.unreached(r0, start.missed)
    problem.scale = float(start.measure.max())
    problem.speed = float(np.einsum("ji,ji->j", start.x_dot, start.x_dot).max())
    z, nodes = np.append(r0, 1.0), start  # σ = s / s₀
    bounds = list(box) * len(r0) + [(0.0, None)]
    iterations, success, message = 0, True, ""
    for tie_break in (True, False) if polish else (True,):
        problem.tie_break = tie_break
        # one BLAS thread: the sums SLSQP's steps take, and so where it ends, are then the same
        # in any process (a notebook, a map's Dask worker, the command), however many cores
        with threadpool_limits(limits=1, user_api="blas"):
            solution = minimize(
                problem.cost,
                z,
                jac=True,
                method="SLSQP",
                bounds=bounds,
                constraints=[{"type": "ineq", "fun": problem.constraints, "jac": problem.jacobian}],
                options={
                    "maxiter": ITERATIONS,
                    "ftol": FUNCTION_TOLERANCE if tie_break else POLISH_TOLERANCE,
                },
            )
        iterations += solution.nit
        found = problem.evaluate(solution.x)
        worse = _worse(problem, box, (solution.x, found), (z, nodes))
        if worse:  # kept where it was: the solver's answer is no optimum of this problem
            success, message = False, f"{solution.message}; {worse}, kept the history before"
            continue
        z, nodes = solution.x, found
        success, message = bool(solution.success), str(solution.message)
    grid = GridSolution(
        intervals,
        float(nodes.measure.max()),
        success,
        int(iterations),
        message,
        float(max(0.0, -problem.slack(z, nodes).min())),
    )
    return problem.held(z), grid, nodes


def _worse(problem: Transcription, box: list, answer: tuple, before: tuple) -> str | None:
    """Why the solver's ``answer`` (z, its nodes) is worse than the history it started from
    (``before``, the same), or None: a node it does not reach; strokes further past their
    limits (`excess`) by more than `LIMIT_MARGIN`; or, as far inside them, a peak higher by
    more than the tie-break may trade (`SMOOTHING`). SLSQP may end so where the problem is
    badly scaled (the Panda's four held joints); the least peak found then stays."""
    (z, nodes), (z_0, nodes_0) = answer, before
    if nodes.missed.any():
        return f"it left the task at {int(nodes.missed.sum())} nodes"
    excess, excess_0 = _excess(problem, box, z, nodes), _excess(problem, box, z_0, nodes_0)
    if excess > excess_0 + LIMIT_MARGIN:
        return f"it ended {excess:.3g} of a stroke past its limits ({excess_0:.3g} before)"
    peak, peak_0 = float(nodes.measure.max()), float(nodes_0.measure.max())
    if excess >= excess_0 - LIMIT_MARGIN and peak > peak_0 * (1 + SMOOTHING):
        return f"it ended at a peak {peak / peak_0:.4g} times the one it started from"
    return None


def _excess(problem: Transcription, box: list, z: np.ndarray, nodes: Nodes) -> float:
    """How far the history z (its ``nodes``) is past a checked stroke, a fraction of it: the
    held actuators' beyond their ``box`` (lower, upper; None where open) too."""
    held = problem.held(z)
    past = [0.0, float(-problem.margins(nodes).min(initial=0.0))]
    for column, (lower, upper) in enumerate(box):
        span = upper - lower if lower is not None and upper is not None else 1.0
        if lower is not None:
            past.append(float((lower - held[:, column]).max()) / span)
        if upper is not None:
            past.append(float((held[:, column] - upper).max()) / span)
    return max(past)


def resampled(times: np.ndarray, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (k, c) sampled at times t (k,), linearly interpolated at ``times``, (T, c)."""
    return np.stack([np.interp(times, t, column) for column in values.T], axis=1)


def global_optimum(
    robot: Robot,
    segment: Segment | Chain,
    objective: Objective = VELOCITY,
    held: str | Sequence[str] | None = None,
    checked: tuple[str, ...] | None = None,
    grids: tuple[int, ...] | None = None,
    initial: Sequence | None = None,
    search: SearchResult | None = None,
) -> GlobalOptimum:
    """The motion along ``segment`` (any path: a segment, or a chain of them) of least peak of
    ``objective`` over every history of the held actuators (one name, or the r names of a task
    with r held; by default `held_actuators`; see the module docstring), on each of ``grids``
    (intervals) in turn; by default `GRIDS`, then grids twice as fine while the last refinement
    still moves the optimum by `redundancy.planning.refinement.CONVERGED` or more, up to
    `MAX_INTERVALS`.

    The problem is not convex: the first grid is solved from the law's motion from each
    ``initial`` start (held strokes at t = 0, m or rad, one value or (r,) each; by default the
    best start of the improved method's ``search``, by default its fast search or with several
    held its sweep, and `CANDIDATES` starts evenly over the box of the starts it reached,
    feasible or not: the excavator's least kinetic-energy scrape starts outside the feasible
    ones), and the least optimum is refined through the later grids, each from the previous
    one. ``checked`` names the actuators whose strokes bind (default all). The objective must
    be a peak objective (its reduction "peak").
    """
    require_robot(robot)
    segment, objective = checked_path(segment), as_objective(objective)
    names = chosen_held(robot, segment, held)
    rows = held_indices(robot, names)
    refine = grids is None
    grids = checked_grids(GRIDS if grids is None else grids, 3)
    if objective.reduction != "peak":
        raise InvalidInputError(
            f"the bound minimises a peak; objective {objective.name!r} reduces its measure by "
            f"{objective.reduction!r}: its least value is redundancy.integral_optimum's"
        )
    limits = Limits.strokes(robot, checked)
    near = None
    if initial is None:
        initial, near = _initial(robot, segment, objective, names, checked, search)
    values = np.array(initial, dtype=float).reshape(len(initial), len(rows))
    others = Limits.strokes(robot, [name for name in limits.names if name not in names])
    box = [
        (robot.actuators[n].lower, robot.actuators[n].upper) if n in limits.names else (None, None)
        for n in names
    ]

    def solve(intervals: int, t: np.ndarray, r: np.ndarray, t_q: np.ndarray, q: np.ndarray):
        """The optimum on a grid, from r (k, r) sampled at times t and q at times t_q; its r,
        solution, nodes and the problem."""
        q = resampled(node_times(segment, intervals), t_q, q)
        problem = Transcription(robot, objective, segment, rows, others, intervals, q)
        r = resampled(problem.unknown_times(), t, r)
        return (*solve_transcription(problem, r, box, intervals, polish=True), problem)

    candidates = _from_each_start(robot, segment, objective, names, values, grids[0], solve, near)
    r, grid, nodes, problem = min(candidates, key=lambda c: c[1].peak)
    solutions = [grid]
    finer = list(grids[1:])
    while finer:
        intervals = finer.pop(0)  # a path's unknowns are in time order: it is not periodic
        r, grid, nodes, problem = solve(
            intervals, problem.unknown_times(), r, problem.t, nodes.space.q
        )
        solutions.append(grid)
        if refine and not finer and not Grids(tuple(solutions)).converged:
            finer = [2 * intervals] if 2 * intervals <= MAX_INTERVALS else []
    optimum = Trajectory.single(
        robot,
        segment,  # type: ignore[arg-type]
        objective.resolver,
        problem.t,
        nodes.space,
        nodes.x_dot,
        limits.names,
        objective,
        nodes.measure,
    )
    one = len(names) == 1
    return GlobalOptimum(
        segment,
        objective,
        names[0] if one else names,
        optimum,
        float(r[0, 0]) if one else tuple(r[0].tolist()),
        tuple(solutions),
    )


def _initial(
    robot, segment, objective, names, checked, search
) -> tuple[list[tuple], np.ndarray | None]:
    """The bound's default starts of `global_optimum`, distinct and best first, and, with one
    held actuator, the best start's configuration, on the branch the search chose."""
    if search is None:
        search = improved_start(robot, segment, objective, names, checked=checked)
    if search.best is None:
        raise InvalidInputError(
            f"no start on {segment.label} keeps every checked stroke for the "
            f"{objective.name} objective; the global optimum starts from feasible motions"
        )
    reachable = np.array([s.values for s in search.samples if s.peak is not None])
    spread = np.linspace(reachable.min(0), reachable.max(0), CANDIDATES)
    near = search.start_configuration(search.best) if len(names) == 1 else None
    return list(dict.fromkeys(map(tuple, [search.best.values, *spread.tolist()]))), near


def _from_each_start(robot, segment, objective, names, values, intervals, solve, near) -> list:
    """``solve`` on the first grid of ``intervals`` from the law's motion from each start of
    ``values`` (k, r) that reaches the path's start: on the assembly branch of ``near`` (a
    start configuration (n,), one held actuator) by continuation from it, else the
    configuration inverse kinematics picks; the solutions, or one line naming why each start
    failed."""
    rows = held_indices(robot, names)
    if near is None:
        found = inverse_kinematics(robot, segment.start, names, values)
        q, reached = found.q, found.reached
    else:
        starts = Configurations.near(robot, segment, names[0], near).at(values[:, 0])
        q, reached = starts.q, starts.reachable
    if not reached.any():
        raise UnreachableError(
            f"{robot.name} cannot reach the start {segment.start.tolist()} of {segment.label} "
            f"at any of {'; '.join(named_values(robot, names, v) for v in values)}"
        )
    motions = simulate_path(
        robot, objective.resolver, segment, q[reached], segment.duration / intervals
    )
    candidates, failures = [], []
    for i, value in enumerate(values[reached]):
        try:
            t = motions.t[i]
            candidates.append(solve(intervals, t, motions.x[i][:, rows], t, motions.q[i]))
        except InvalidInputError as error:  # the solver stepped where the task is out of reach
            at = named_values(robot, names, value)
            failures.append(f"from {at}: {error}")
    if not candidates:
        raise InvalidInputError(f"the bound found no optimum; {'; '.join(failures)}")
    return candidates
