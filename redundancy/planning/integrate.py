"""Integration of a law along a segment, for a batch of starting configurations at once.

The joint state follows q̇ = A⁻¹ ẋ (Eq. 11), ẋ from the law (`Resolver.resolve`) for the task
velocity, with closed-loop correction where a gain K (1/s) is given: ẏ = ẏ_d + K (y_d(t) − y(q)).
Two methods, one result type (`Trajectory`):

- "adaptive" (the default): Dormand-Prince 5(4) with error control on q (relative and absolute
  ``tolerance``), open loop (K = 0) unless a gain is given, on scipy's RK45 tableau. The loop is
  written here because every start keeps its own step size while each stage is one batched
  evaluation of the starts still running: `solve_ivp` steps one system at one size (a batch as
  one system moves at the pace of its hardest start; one call per start evaluates the law state
  by state). Samples lie on the uniform grid of ``time_step`` by the 4th-order dense output
  (Shampine's) or, with ``sparse``, at the accepted steps and their midpoints: strokes between
  them follow the cubic Hermite interpolant through x and ẋ, and count `ALLOWANCE` ×
  ``tolerance`` closer to their limits (the start itself exact), so a start feasible on sparse
  samples is feasible on the grid too. The accepted steps are kept (`Steps`), so a sparse motion
  is put on a grid later by one batched evaluation (`Trajectory.on_grid`), not integrated again.
- "rk4": classical Runge-Kutta on the grid of ``time_step``, closed loop with K = `GAIN` by
  default (the paper's fixed-step simulation).

A start whose actuator Jacobian turns singular, whose state stops being finite, or where an
actuator cannot be evaluated (a cylinder of zero length, a four-bar linkage that cannot close,
past its toggle) is frozen there and flagged (`Trajectory.failed`, `FAILED`), so one bad start
never spoils the batch. So is an adaptive one that has tried `MAX_STEPS` steps short of the end,
beyond the one step each of the path's breaks (a recorded path's points) forces, or whose last
`MAX_SINGULAR` accepted steps all ended at a J_H singular to the law's ratio, where it damps its
solve (`redundancy.resolution.laws`; a built-in weighted law on built-in actuator kinds, which
the core runs: a held law, or a law or kind of your own, runs on to `MAX_STEPS`): where the path
leaves the arm's reach, the law holds the tool at its edge and chatters, and the steps shrink to
a millionth of the duration and would run on for a million of them, each kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, partial
from typing import TYPE_CHECKING, NamedTuple, cast

import numpy as np
from scipy.integrate import RK45

from redundancy import _core
from redundancy.errors import InvalidInputError
from redundancy.model.hydraulics import BAR, LITRES_PER_MINUTE, Flows, Supply
from redundancy.model.kinematics import join
from redundancy.model.robot import Robot, require_robot
from redundancy.model.values import is_finite
from redundancy.planning.tasks import SAME_TIME, Chain, Segment, jumps
from redundancy.resolution.laws import Resolver, compiled_rates, require_resolver
from redundancy.resolution.limits import TOLERANCE as LIMIT_TOLERANCE
from redundancy.resolution.limits import Limits, Violation, hydraulic_values
from redundancy.resolution.objectives import ENERGY, VELOCITY, Objective, integral
from redundancy.resolution.state import (
    ActuatorSpace,
    compiled_space,
    evaluate,
    joined_found,
    regularised,
)

if TYPE_CHECKING:
    import pandas as pd

TIME_STEP = 0.01  # s
MAX_STEPS = 2_000  # an adaptive motion's steps, tried, per segment beyond one per break (the
# bundled robots' take 3-40 at the reports' tolerance; a recorded path has a break per point)
MAX_SINGULAR = 50  # accepted steps in a row ending at a singular J_H (the law damping its solve)
# that fail a motion: where its path leaves the arm's reach it would crawl on for 1,000s of them
FAILED = (  # why a motion failed (`Trajectory.failed`), in words
    "where A turned singular or an actuator could not be evaluated (a cylinder of zero length, "
    f"a linkage that cannot close), or where its steps shrank to a crawl ({MAX_STEPS:,} steps "
    f"short of the end, or {MAX_SINGULAR} in a row at a singular J_H: the law chattering, as "
    "where the path leaves the arm's reach)"
)
MIN_INTERVALS = 10  # of a motion's grid, however short its segment
MAX_INTERVALS = 1_000_000  # of a motion's grid: 24 MB of q alone for a 3-joint robot
GAIN = 20.0  # K, 1/s, of the fixed-step method
RK4_STABLE = 2.785  # −K h of the classical Runge-Kutta method's stability limit on the
# negative real axis (|1 + z + z²/2 + z³/6 + z⁴/24| = 1 at z = −2.7853): beyond it the closed
# loop's tracking error grows step by step
TOLERANCE = 1e-6  # relative and absolute error per adaptive step on q (rad, m)
REPORT_TOLERANCE = 1e-10  # of a motion reported on its grid: its dense output's rate then
# matches the law's q̇, so that the power balance Σ F ẋ = d(T + V)/dt holds on the grid (at
# `TOLERANCE` it misses by 1e-4 of the peak power, the dense output's own error over a step)
ALLOWANCE = 30  # sparse samples' strokes count ALLOWANCE × tolerance (m) closer to their
# limits: the integrator's error in x, measured below 6 × tolerance on the crane
METHODS = ("adaptive", "rk4")

# Dormand-Prince 5(4), the tableau scipy's RK45 integrates with: the stage nodes c (the last
# stage, at c = 1, gives the next step's first slope), the stage weights a (row i: stage i + 1's;
# the last row gives the 5th-order step), the error weights e (4th − 5th order), and the dense
# output, whose weights at θ of a step are P · (θ, θ², θ³, θ⁴) (Shampine, 1986).
TABLEAU = (
    np.append(RK45.C[1:], 1.0),
    np.vstack([np.pad(RK45.A[1:], ((0, 0), (0, 1))), RK45.B]),
    RK45.E,
)
DENSE = RK45.P


@dataclass(frozen=True, eq=False)
class Trajectory:
    """k motions along one path: their sample times and the states the integrator computed
    there.

    t (k, T) sample times, s (a motion with fewer samples repeats its last); ``space`` the
    states at the samples as the integrator evaluated them, one flat batch of k·T, motion by
    motion, v = q̇: q (k, T, n) joints, x (k, T, n) actuator strokes (m) and y (k, T, m) tool
    are read from it, and so is every quantity along the motion (`states`); x_dot (k, T, n)
    actuator velocities (m/s); failed (k,) starts frozen at a bad state (`FAILED`);
    stopped (k,) motions a search stopped past their limits; checked: the actuators whose
    strokes count; measure (k, T) the measure of ``objective`` at the samples, when integrated
    for one; ``sparse``: sampled at the adaptive steps (see the module docstring), with the
    strokes' error ``allowance`` (m); ``circuit``: the hydraulic circuit's limits count too
    (`within_limits`, `violations`). ``pieces``: a chain's motions as integrated, segment by
    segment, which `on_grid` samples again.
    """

    robot: Robot = field(repr=False)
    segment: Segment | Chain
    resolver: Resolver
    t: np.ndarray
    space: ActuatorSpace = field(repr=False)
    x_dot: np.ndarray
    failed: np.ndarray
    stopped: np.ndarray
    checked: tuple[str, ...]
    objective: Objective | None = None
    measure: np.ndarray | None = None
    sparse: bool = False
    allowance: float = 0.0
    circuit: bool = False
    steps: Steps | None = field(default=None, repr=False)
    pieces: tuple[Trajectory, ...] = field(default=(), repr=False)

    @classmethod
    def single(
        cls,
        robot: Robot,
        segment: Segment,
        resolver: Resolver,
        t: np.ndarray,
        space: ActuatorSpace,
        x_dot: np.ndarray,
        checked: tuple[str, ...],
        objective: Objective | None = None,
        measure: np.ndarray | None = None,
    ) -> Trajectory:
        """One motion that ran to its end, from its sample times t (T,), the states there
        (a batch of T) and ẋ (T, n), and, for ``objective``, its ``measure`` (T,)."""
        done = np.zeros(1, dtype=bool)  # neither failed nor stopped
        return cls(
            robot=robot,
            segment=segment,
            resolver=resolver,
            t=t[None],
            space=space.moving(space.joint_velocities(x_dot)),
            x_dot=x_dot[None],
            failed=done,
            stopped=done,
            checked=checked,
            objective=objective,
            measure=None if measure is None else measure[None],
        )

    def __len__(self) -> int:
        return len(self.t)

    @property
    def counts(self) -> np.ndarray:
        """How many samples each motion has (k,): the rest repeat its last."""
        return np.array([np.searchsorted(times, times[-1]) + 1 for times in self.t])

    def _motions(self, flat: np.ndarray) -> np.ndarray:
        """Values at the k·T samples, (k·T, ...), as (k, T, ...)."""
        return flat.reshape(*self.t.shape, *flat.shape[1:])

    @property
    def q(self) -> np.ndarray:
        """Joints q (k, T, n), m or rad."""
        return self._motions(self.space.q)

    @property
    def x(self) -> np.ndarray:
        """Actuator strokes x (k, T, n), m (rad for a rotary actuator)."""
        return self._motions(self.space.x)

    @property
    def y(self) -> np.ndarray:
        """The tool y (k, T, m), m (and rad for the tool's angle)."""
        return self._motions(self.space.y)

    def select(self, rows) -> Trajectory:
        """The motions ``rows`` (distinct indices) alone."""
        rows = np.atleast_1d(rows)
        T = self.t.shape[1]
        return replace(
            self,
            t=self.t[rows],
            space=self.space.take((rows[:, None] * T + np.arange(T)).ravel()),
            x_dot=self.x_dot[rows],
            failed=self.failed[rows],
            stopped=self.stopped[rows],
            measure=None if self.measure is None else self.measure[rows],
            steps=None if self.steps is None else self.steps.select(rows, len(self)),
            pieces=tuple(piece.select(rows) for piece in self.pieces),
        )

    def on_grid(self, time_step: float = TIME_STEP) -> Trajectory:
        """These motions sampled on the uniform grid of ``time_step`` by the dense output of the
        steps they were integrated with, as `simulate` samples them without ``sparse``: no
        integration again (a chain's segment by segment). A motion a search stopped stays where
        it was stopped."""
        if self.pieces:
            pieces = [piece.on_grid(time_step) for piece in self.pieces]
            return chained(self.segment, pieces)  # type: ignore[arg-type]
        if self.steps is None:
            raise InvalidInputError("only adaptively integrated motions can be sampled again")
        grid = time_grid(self.segment, time_step)  # type: ignore[arg-type]
        samples = on_grid(self.steps, grid, self.failed, self.stopped)
        return replace(self, sparse=False, allowance=0.0, **samples)

    def to_frame(self, i: int = 0) -> pd.DataFrame:
        """Motion ``i`` as a table, one row per sample: t, the joints q, per actuator x, ẋ, ẍ
        and F_H (where the robot has masses), each column named with its unit (a rotary
        actuator's in rad and N·m); where the machine has a hydraulic circuit, per cylinder the
        load pressure p_L (bar) and flow Q (L/min), and the pump's flow (L/min) and its power
        p_P Q_P (kW) under the machine's supply, which the column names (pump_power_LS (kW)
        under load sensing)."""
        import pandas as pd

        robot = self.robot
        joints = ["rad" if r else "m" for r in robot.rotary_joints]
        rotary = robot.actuators.rotary
        columns = {"t (s)": self.t[i]}
        for j, (name, unit) in enumerate(zip(robot.joint_names, joints)):
            columns[f"q_{name} ({unit})"] = self.q[i, :, j]
        parts = [
            ("x", self.x, ("m", "rad")),
            ("x_dot", self.x_dot, ("m/s", "rad/s")),
            ("x_ddot", self.x_ddot, ("m/s²", "rad/s²")),
        ]
        if not robot.kinematic_only:
            parts.append(("F", self.forces, ("N", "N·m")))
        for part, values, units in parts:
            for a, name in enumerate(robot.actuators.names):
                columns[f"{part}_{name} ({units[int(rotary[a])]})"] = values[i, :, a]
        if robot.hydraulics is not None and not robot.kinematic_only:
            circuit, flows = robot.hydraulics, self.flows
            for c, name in enumerate(circuit.names):
                columns[f"p_L_{name} (bar)"] = flows.load[i, :, c] / BAR
                columns[f"Q_{name} (L/min)"] = flows.flow[i, :, c] / LITRES_PER_MINUTE
            columns["Q_pump (L/min)"] = flows.pump_flow[i] / LITRES_PER_MINUTE
            columns[f"pump_power_{circuit.supply.name} (kW)"] = flows.power(circuit.supply)[i] / 1e3
        return pd.DataFrame(columns)

    @cached_property
    def limits(self) -> Limits:
        """The checked actuators' strokes."""
        return Limits.strokes(self.robot, self.checked)

    @cached_property
    def states(self) -> ActuatorSpace:
        """The states at every sample, with ẍ (`x_ddot`), as one flat batch of k·T."""
        return self.space.moving(self.space.v, self._flat(self.x_ddot))  # type: ignore[arg-type]

    def _flat(self, values: np.ndarray) -> np.ndarray:
        """Values at the samples, (k, T, ...), as one flat batch (k·T, ...)."""
        return values.reshape(-1, *values.shape[2:])

    def values(self, objective: Objective) -> np.ndarray:
        """``objective``'s measure at every sample (k, T)."""
        if objective is self.objective and self.measure is not None:
            return self.measure
        return self._motions(objective.measure(self.states, self._flat(self.x_dot)))

    def score(self, objective: Objective) -> np.ndarray:
        """``objective`` over each motion (k,): its measure's peak or integral; on sparse
        samples, by Simpson's rule on every step where the measure is exact at the samples
        (`redundancy.resolution.objectives.integral`). A dynamic one reads ẍ from differences
        of the samples' ẋ (`x_ddot`), errors Simpson's order does not beat: its trapezoids
        stay (on the crane's LS pump energy, Simpson's rule missed the grid's integral by up to
        2.3 %, the trapezoids by 1.1 %)."""
        steps = self.sparse and not objective.dynamic
        return objective.reduce(
            self.t, self.values(objective), jumps(self.segment) if steps else None
        )

    @cached_property
    def M_H(self) -> np.ndarray:
        """M_H (k, T, n, n) along the motion, kg."""
        return self._motions(self.states.M_H)

    @cached_property
    def x_ddot(self) -> np.ndarray:
        """ẍ (k, T, n) in m/s², by differences of ẋ in time (`rate_on_grid`) within each piece
        of the path between its `breaks`, where ẏ_d is not smooth: no difference spans a corner
        the path turns at speed, where ẋ jumps, so ẍ does not grow as the samples get closer
        there (the corner's impulse is not in it), nor a ramp's end, where ẍ jumps. A sample at
        a break ends the piece before it (its ẋ is that piece's). Each motion's own samples
        (repeated last samples repeat the last value); a motion of its start alone, frozen
        there, is at rest."""
        out = np.zeros_like(self.x_dot)
        breaks, duration = self.segment.breaks, self.segment.duration
        if np.all(self.t == self.t[:1]):  # one time for every motion: at once
            for piece in _pieces(self.t[0], breaks, duration):
                out[:, piece] = rate_on_grid(self.x_dot[:, piece], self.t[0, piece])
            return out
        for i, (times, count) in enumerate(zip(self.t, self.counts)):
            for piece in _pieces(times[:count], breaks, duration):
                out[i, piece] = rate_on_grid(self.x_dot[i : i + 1, piece], times[piece])[0]
            out[i, count:] = out[i, count - 1]
        return out

    @cached_property
    def forces(self) -> np.ndarray:
        """Actuator forces F_H = M_H ẍ + N_H (k, T, n) (Eq. 21), N."""
        return self._motions(self.states.F_H)

    @cached_property
    def flows(self) -> Flows:
        """The robot's hydraulic circuit along the motion, (k, T, c) per cylinder
        (`redundancy.model.hydraulics`)."""
        return self.robot.circuit().flows(self.x_dot, self.forces)

    def energy(self, supply: Supply | None = None) -> np.ndarray:
        """Pump energy E = ∫ p_P Q_P dt (k,), J, under ``supply`` (default the machine's)."""
        supply = supply or self.robot.circuit().supply
        return integral(self.t, self.flows.power(supply))

    @cached_property
    def hydraulic_limits(self) -> Limits:
        """The circuit's limits (`Limits.hydraulic`), on `hydraulic_values`."""
        return Limits.hydraulic(self.robot)

    @cached_property
    def hydraulic_values(self) -> np.ndarray:
        """What the circuit's limits bound, (k, T, 2c + 1): each cylinder's load pressure (Pa),
        the pump flow (m³/s), each cylinder's speed (m/s)."""
        return hydraulic_values(self.robot.circuit(), self.x_dot, self.flows)

    def hydraulic_violations(self, i: int) -> list[Violation]:
        """Every interval over which motion ``i`` passes a limit of the circuit, at its
        samples."""
        return self.hydraulic_limits.violations(self.t[[i]], self.hydraulic_values[[i]])[0]

    @property
    def velocity_norm(self) -> np.ndarray:
        """ẋᵀẋ (k, T), m²/s²."""
        return self.values(VELOCITY)

    @property
    def kinetic(self) -> np.ndarray:
        """ẋᵀ M_H ẋ (k, T) = twice the kinetic energy (Eq. 28), J."""
        return self.values(ENERGY)

    @property
    def peak_velocity_norm(self) -> np.ndarray:
        """max_t ẋᵀẋ (k,), m²/s²."""
        return self.score(VELOCITY)

    @property
    def peak_kinetic(self) -> np.ndarray:
        """max_t ẋᵀ M_H ẋ (k,), J: twice the peak kinetic energy."""
        return self.score(ENERGY)

    @property
    def tracking_error(self) -> np.ndarray:
        """|y(t) − y_d(t)| (k, T), in m."""
        return np.linalg.norm(self.y - self.segment.position(self.t), axis=2)

    @property
    def max_tracking_error(self) -> np.ndarray:
        """max_t |y − y_d| (k,), in m."""
        return self.tracking_error.max(axis=1)

    @cached_property
    def margins(self) -> np.ndarray:
        """The least margin of the checked strokes over each motion (k,), m or rad (negative
        past a limit; −inf where the motion failed or was stopped): at the samples, and for
        sparse samples also between them (Hermite) less the error allowance."""
        limits = self.limits
        start = limits.margin(self.x[:, 0])
        if self.sparse:
            lowest, highest = stroke_extremes(self.t, self.x, self.x_dot)
            along = limits.range_margin(lowest, highest) - self.allowance
        else:
            along = limits.margin(self.x[:, 1:]).min(axis=1)
        return np.where(self.failed | self.stopped, -np.inf, np.minimum(start, along))

    @property
    def within_limits(self) -> np.ndarray:
        """Whether each motion keeps every checked actuator inside its stroke (k,), and, where
        the circuit counts, within every limit of the circuit at its samples, and did not fail."""
        inside = self.margins >= -LIMIT_TOLERANCE
        return inside & self.within_circuit if self.circuit else inside

    @cached_property
    def within_circuit(self) -> np.ndarray:
        """Whether each motion keeps within every limit of the hydraulic circuit at its samples
        (k,), a hair of relative `LIMIT_TOLERANCE` allowed."""
        limits = self.hydraulic_limits
        excess = limits.excess(self.hydraulic_values) / limits.upper
        return excess.max(axis=(1, 2)) <= LIMIT_TOLERANCE

    def violations(self, i: int) -> list[Violation]:
        """Every interval over which motion ``i`` has a checked actuator outside its stroke, or,
        where the circuit counts, passes one of its limits, at its samples, in order of time."""
        found = list(self.stroke_violations[i])
        if self.circuit:
            found = sorted(found + self.hydraulic_violations(i), key=lambda v: v.start)
        return found

    @cached_property
    def stroke_violations(self) -> list[list[Violation]]:
        """Each motion's intervals outside a checked stroke, in order of time, found for all
        motions at once. A margin of at least −`LIMIT_TOLERANCE` (a bound on every sample's)
        says a motion has none; the others (a NaN margin too) are scanned."""
        past = np.flatnonzero(~(self.margins >= -LIMIT_TOLERANCE))
        found: list[list[Violation]] = [[] for _ in self.t]
        for i, violations in zip(past, self.limits.violations(self.t[past], self.x[past])):
            found[i] = violations
        return found


def chained(path: Chain, pieces: Sequence[Trajectory]) -> Trajectory:
    """k motions along each segment of ``path`` in turn (each piece starting where the one
    before ended) as k motions along the whole chain: times from the chain's start, each later
    piece's first sample left out (it repeats the corner the one before ended at). A motion
    failed or stopped where any piece did."""
    firsts = np.cumsum([0, *(p.t.size for p in pieces)])
    index = [  # each motion's samples among the pieces' flattened motion by motion
        np.concatenate(
            [
                first + i * p.t.shape[1] + np.arange(min(number, 1), p.counts[i])
                for number, (first, p) in enumerate(zip(firsts, pieces))
            ]
        )
        for i in range(len(pieces[0]))
    ]
    return _gathered(
        path,
        pieces,
        index,
        path.offsets,
        failed=np.any([p.failed for p in pieces], axis=0),
        stopped=np.any([p.stopped for p in pieces], axis=0),
        steps=None,
        pieces=tuple(pieces),
    )


def concatenated(first: Trajectory, second: Trajectory) -> Trajectory:
    """Two batches of motions on one path as one."""
    index = [
        offset + i * part.t.shape[1] + np.arange(part.t.shape[1])
        for offset, part in ((0, first), (first.t.size, second))
        for i in range(len(part))
    ]
    steps = None
    if first.steps is not None and second.steps is not None:
        steps = first.steps.joined(second.steps, len(first))
    pieces = tuple(concatenated(a, b) for a, b in zip(first.pieces, second.pieces))
    return _gathered(
        first.segment,
        (first, second),
        index,
        (0.0, 0.0),
        failed=np.concatenate([first.failed, second.failed]),
        stopped=np.concatenate([first.stopped, second.stopped]),
        steps=steps,
        pieces=pieces,
    )


def _gathered(path, parts: Sequence[Trajectory], index: list[np.ndarray], shifts, **fields):
    """k motions along ``path``, motion i the samples index[i] among the ``parts``' samples
    flattened motion by motion (each part's times shifted by its ``shifts``, s), padded to the
    longest by repeating its last; the other ``fields`` given."""
    length = max(len(i) for i in index)
    rows = np.stack([np.concatenate([i, np.repeat(i[-1:], length - len(i))]) for i in index])

    def gather(name: str) -> np.ndarray:
        arrays = [getattr(p, name) for p in parts]
        return np.concatenate([a.reshape(-1, *a.shape[2:]) for a in arrays])[rows]

    return replace(
        parts[0],
        segment=path,
        t=np.concatenate([p.t.ravel() + shift for p, shift in zip(parts, shifts)])[rows],
        space=ActuatorSpace.joined([p.space for p in parts]).take(rows.ravel()),
        x_dot=gather("x_dot"),
        measure=gather("measure") if all(p.measure is not None for p in parts) else None,
        **fields,
    )


def stroke_extremes(
    t: np.ndarray, x: np.ndarray, x_dot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Least and greatest stroke of every actuator over each motion after its start (the start
    itself excluded; +∞ and −∞ for motions of one sample), (k, n) each, for samples at times
    t (k, T) of x and ẋ (k, T, n).

    Between samples x follows the cubic Hermite interpolant through x and ẋ at both ends, p(s) =
    a s³ + b s² + d₀ s + x₀ over s ∈ [0, 1] with d = h ẋ; its interior extrema are where its
    derivative, a quadratic, vanishes. One pass of the core (`redundancy._core.stroke_extremes`).
    """
    return _core.stroke_extremes(t, x, x_dot)


def rate_on_grid(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """d/dt of ``values`` (k, T, ...) sampled at times t (T,): second-order differences (first-
    order ones of two samples, 0 for one), and on a uniform grid of five samples or more
    (f₋₂ − 8 f₋₁ + 8 f₁ − f₂) / 12h inside, O(h⁴)."""
    if len(t) < 2:
        return np.zeros_like(values)
    rate = np.gradient(values, t, axis=1, edge_order=2 if len(t) > 2 else 1)
    steps = np.diff(t)
    if len(t) >= 5 and np.all(np.abs(steps - steps[0]) <= 1e-9 * steps[0]):
        f, h = values, steps[0]
        rate[:, 2:-2] = (f[:, :-4] - 8 * f[:, 1:-3] + 8 * f[:, 3:-1] - f[:, 4:]) / (12 * h)
    return rate


def _pieces(t: np.ndarray, breaks: np.ndarray, duration: float) -> list[slice]:
    """The runs of samples at times t (T,) between the ``breaks`` (a sample within 1e-9 of the
    ``duration`` after a break, or before it, ends the run before), as slices; a run of one
    sample joins the one before it (or after it, first), where its ẋ alone gives no rate."""
    piece = np.searchsorted(breaks, t - 1e-9 * duration, side="left")
    starts = [0, *(np.flatnonzero(np.diff(piece)) + 1)]
    runs: list[list[int]] = []
    for a, b in zip(starts, [*starts[1:], len(t)]):
        if runs and (b - a == 1 or runs[-1][1] - runs[-1][0] == 1):
            runs[-1][1] = b
        else:
            runs.append([a, b])
    return [slice(a, b) for a, b in runs]


def time_grid(segment: Segment, time_step: float = TIME_STEP) -> np.ndarray:
    """Uniform sample times over the segment, at most ``time_step`` apart, (T,) in s; at least
    `MIN_INTERVALS` intervals, so that a segment shorter than a few steps is still resolved
    (ẍ by second-order differences, the fastest timing of its path by TOPP-RA)."""
    steps = max(MIN_INTERVALS, int(np.ceil(segment.duration / time_step - 1e-9)))
    if steps > MAX_INTERVALS:
        raise InvalidInputError(
            f"time_step {time_step:g} s makes {steps:,} intervals of segment {segment.name} "
            f"({segment.duration:.3g} s); at most {MAX_INTERVALS:,}: give a time_step of at "
            f"least {segment.duration / MAX_INTERVALS:.3g} s"
        )
    return np.linspace(0.0, segment.duration, steps + 1)


class Rates(NamedTuple):
    """The law at k states: ẋ (k, n); the states themselves, at v = q̇ (``space``: q, x, y,
    A, J, ...); the objective's measure (k,) or None; bad (k,) where A is singular, the state
    not finite or an actuator not evaluated (there q̇ = ẋ = 0)."""

    x_dot: np.ndarray
    space: ActuatorSpace
    measure: np.ndarray | None
    bad: np.ndarray

    @property
    def q_dot(self) -> np.ndarray:
        """q̇ = A⁻¹ ẋ (k, n) (Eq. 11): the states' own v."""
        return self.space.v  # type: ignore[return-value]

    def take(self, rows: np.ndarray) -> Rates:
        """The rates of the states ``rows`` (indices or a mask) alone."""
        measure = None if self.measure is None else self.measure[rows]
        return Rates(self.x_dot[rows], self.space.take(rows), measure, self.bad[rows])


class Law:
    """The right-hand side q̇(t, q) of a law along a segment, evaluated for a batch of states."""

    def __init__(self, robot, resolver, segment, gain, objective):
        self.robot, self.resolver, self.segment = robot, resolver, segment
        self.gain, self.objective = gain, objective

    def velocity(self, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The task velocity ẏ (k, m) the law resolves at times t (k,) where the tool is at
        y (k, m): ẏ_d(t), plus K (y_d(t) − y) in closed loop."""
        y_dot = self.segment.velocity_at(t)
        if self.gain:
            y_dot = y_dot + self.gain * (self.segment.position(t) - y)
        return y_dot

    @property
    def loop_velocity(self):
        """What the core's loop reads ẏ from: on a steady segment, where ẏ_d is constant and
        y_d(t) = y_d(0) + ẏ_d t, ẏ_d itself (m,) in open loop and (y_d(0), ẏ_d, K) in closed
        loop; else `velocity`, called once per batch."""
        if not (isinstance(self.segment, Segment) and self.segment.steady):
            return self.velocity
        if not self.gain:
            return self.segment.velocity
        return self.segment.position(0.0), self.segment.velocity, float(self.gain)

    @cached_property
    def compiled(self) -> _core.Rates | None:
        """The law's compiled right-hand side (`compiled_rates`), or None: a kind, a task or a
        law of your own."""
        return compiled_rates(self.robot, self.resolver)

    def __getstate__(self) -> dict:
        """The law as sent to another process (a motion's steps keep it): without its compiled
        right-hand side, which is not picklable and is built again there when needed."""
        return {name: value for name, value in vars(self).items() if name != "compiled"}

    def __call__(self, t: np.ndarray, q: np.ndarray) -> Rates:
        """At times t (k,) and configurations q (k, n): `evaluated`, as `Rates`."""
        return self.rates([self.evaluated(t, q)])

    def evaluated(self, t: np.ndarray, q: np.ndarray) -> Rates | tuple:
        """The law at times t (k,) and configurations q (k, n), as a record for `rates`: by one
        call of the compiled right-hand side where there is one and it serves the states (the
        evaluator's arrays, ẋ and q̇), else `Rates` in Python, alike to rounding."""
        record = None if self.compiled is None else self.compiled(t, q, self.loop_velocity)
        return self._python(t, q) if record is None else record

    def rates(self, records: Sequence[Rates | tuple], rows: np.ndarray | None = None) -> Rates:
        """The `Rates` of ``records`` (`evaluated`'s, `stage`'s, or the core loop's records of
        the ends of its steps) joined into one batch in order, and of its states ``rows`` alone
        where given: one join and one take, however many batches the samples came in."""
        if len(records) == 1:
            rates = self._record_rates(records[0])
        elif any(isinstance(record, Rates) for record in records):  # in Python, in part or all
            rates = joined([self._record_rates(record) for record in records])
        else:
            raw = cast(Sequence[tuple], records)
            found = joined_found([record[0] for record in raw])
            x_dot, q_dot = (np.concatenate([record[i] for record in raw]) for i in (1, 2))
            rates = self._record_rates((found, x_dot, q_dot))
        return rates if rows is None else rates.take(rows)

    def _record_rates(self, record: Rates | tuple) -> Rates:
        """The `Rates` of one record: itself, or those of the compiled right-hand side's."""
        if isinstance(record, Rates):
            return record
        found, x_dot, q_dot = record
        space, bad = regularised(compiled_space(self.robot, found))
        return self._rates(space, x_dot, q_dot, bad)

    def _python(self, t: np.ndarray, q: np.ndarray) -> Rates:
        """`evaluated` in Python: the evaluation, the law's own methods, the solve for q̇. A state
        whose ẏ is not finite (a task of your own out of its domain) is bad, as the compiled
        right-hand side finds it."""
        space, bad = regularised(evaluate(self.robot, q))
        with np.errstate(over="ignore", invalid="ignore"):  # such a state is bad, said below
            y_dot = self.velocity(t, space.y)
        bad |= ~np.isfinite(y_dot).all(axis=1)
        x_dot = self.resolver.resolve_at(space, np.where(bad[:, None], 0.0, y_dot), t)
        q_dot = _core.solve(space.A, x_dot)  # q̇ = A⁻¹ ẋ of any ẋ: one not finite makes it bad
        bad |= ~np.isfinite(q_dot).all(axis=1)
        if bad.any():
            q_dot[bad], x_dot[bad] = 0.0, 0.0
        return self._rates(space, x_dot, q_dot, bad)

    def _rates(self, space: ActuatorSpace, x_dot, q_dot, bad) -> Rates:
        measure = None if self.objective is None else self.objective.measure(space, x_dot)
        return Rates(x_dot, space.moving(q_dot), measure, bad)

    def stage(self, t: np.ndarray, q: np.ndarray) -> tuple:
        """The law at a stage of the core's integration loop, which calls it where its compiled
        right-hand side does not serve: (its `Rates`, q̇, bad, x), in Python."""
        rates = self._python(t, q)
        return rates, rates.q_dot, rates.bad, rates.space.x


def simulate(
    robot: Robot,
    resolver: Resolver,
    segment: Segment,
    starts: np.ndarray,
    time_step: float = TIME_STEP,
    gain: float | None = None,
    checked: tuple[str, ...] | None = None,
    method: str = "adaptive",
    tolerance: float = TOLERANCE,
    objective: Objective | None = None,
    sparse: bool = False,
    stop_past: bool = False,
    circuit: bool = False,
) -> Trajectory:
    """Integrate ``resolver`` along ``segment`` from every start (k, n) at once.

    ``method`` "adaptive" or "rk4" (see the module docstring); ``gain`` K of the closed loop,
    1/s (default `GAIN` for "rk4", 0 for "adaptive"); ``checked`` the actuators whose strokes
    count for `Trajectory.within_limits` (default all); ``objective`` records its measure at the
    samples. Adaptive only: ``sparse`` samples at the steps instead of the grid; ``stop_past``
    stops a motion once it and its neighbours in the batch are all past a checked stroke by more
    than the error allowance (a search's motions that cannot matter). With ``circuit`` the
    hydraulic circuit's limits count for `Trajectory.within_limits` too.
    """
    require_robot(robot)
    require_resolver(resolver)
    starts = robot.configuration(starts, "starts")
    if segment.start.shape != (robot.m,):
        raise InvalidInputError(
            f"segment {segment.name} has {segment.start.size} coordinates; {robot.name}'s task "
            f"has {robot.m} ({robot.task_axes})"
        )
    if method not in METHODS:
        raise InvalidInputError(f"unknown method {method!r}; methods: {', '.join(METHODS)}")
    gain = (GAIN if method == "rk4" else 0.0) if gain is None else gain
    numbers = (time_step, gain, tolerance)
    if not all(is_finite(v) for v in numbers) or not (
        time_step > 0 and gain >= 0 and tolerance > 0
    ):
        raise InvalidInputError(
            f"time_step must be a finite number > 0 s, gain ≥ 0 1/s and tolerance > 0; got "
            f"time_step = {time_step!r}, gain = {gain!r}, tolerance = {tolerance!r}"
        )
    if not len(starts):
        raise InvalidInputError(f"starts must hold at least one configuration, ({robot.n},)")
    limits = Limits.strokes(robot, checked)
    if circuit:
        robot.circuit()  # says how to declare one before any work
    # a dynamic objective's measure needs ẍ, known only on the finished motion
    law = Law(
        robot, resolver, segment, gain, None if objective and objective.dynamic else objective
    )
    grid = time_grid(segment, time_step)
    if method == "rk4" and gain * (grid[1] - grid[0]) >= RK4_STABLE:
        raise InvalidInputError(
            f"gain = {gain:g} 1/s at time_step = {grid[1] - grid[0]:g} s makes the fixed-step "
            f"method unstable: gain × time_step must stay below {RK4_STABLE} (RK4's stability "
            "limit); lower the gain or the time step, or use method='adaptive'"
        )
    steps = None
    if method == "rk4":
        samples = _runge_kutta(law, starts, grid)
        sparse, allowance = False, 0.0
    else:
        allowance = ALLOWANCE * tolerance if sparse else 0.0
        bounds = (limits, allowance) if stop_past else None
        samples, steps = _dormand_prince(
            law, starts, segment.duration, tolerance, grid, sparse, bounds
        )
    return Trajectory(
        robot=robot,
        segment=segment,
        resolver=resolver,
        checked=limits.names,
        objective=objective,
        sparse=sparse,
        allowance=allowance,
        circuit=circuit,
        steps=steps,
        **samples,
    )


def _runge_kutta(law: Law, starts: np.ndarray, t: np.ndarray):
    """The classical Runge-Kutta method on the grid t (T,); samples at every grid time."""
    k, h, q = len(starts), t[1] - t[0], starts
    failed = np.zeros(k, dtype=bool)
    records = []

    def rates(time, state):
        result = law(np.full(k, time), state)
        failed[result.bad] = True
        result.q_dot[failed], result.x_dot[failed] = 0.0, 0.0  # the state's v is q̇ itself
        return result

    for time in t[:-1]:
        first = rates(time, q)
        records.append(first)
        k2 = rates(time + h / 2, q + h / 2 * first.q_dot).q_dot
        k3 = rates(time + h / 2, q + h / 2 * k2).q_dot
        k4 = rates(time + h, q + h * k3).q_dot
        step = h / 6 * (first.q_dot + 2 * k2 + 2 * k3 + k4)
        q = q + np.where(failed[:, None], 0.0, step)
    records.append(rates(t[-1], q))
    rows, times = np.tile(np.arange(k), len(t)), np.repeat(t, k)
    return _assemble(k, rows, times, law.rates(records).take, failed.copy(), np.zeros(k, bool), t)


def _dormand_prince(law, starts, duration, tolerance, grid, sparse, bounds):
    """Dormand-Prince 5(4) with error control, every start with its own step size (see the
    module docstring), by the core's loop (`redundancy._core.dormand_prince`) on the law's
    compiled right-hand side, or on `Law.stage` for a kind or law of your own; samples on
    ``grid`` (T,) or, ``sparse``, at the steps and midpoints, and the accepted `Steps`.
    ``bounds`` = (limits, allowance) stops motions that with both neighbours passed them. No
    step crosses the segment's `breaks` (a speed profile's ramp ends, a polyline's corners)."""
    k, n = starts.shape
    start = law.evaluated(np.zeros(k), starts)
    first = law.rates([start])
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    limits, allowance = bounds or (None, 0.0)
    if limits is not None:
        lower[limits.columns], upper[limits.columns] = limits.lower, limits.upper
    arguments = (
        starts,
        first.q_dot,
        first.bad,
        duration,
        law.segment.breaks,
        SAME_TIME,
        tolerance,
        *TABLEAU,
        lower,
        upper,
        allowance,
        bounds is not None,
        sparse,
        MAX_STEPS + len(law.segment.breaks),  # no step crosses a break
        MAX_SINGULAR,
    )
    rates, velocity = law.compiled, law.loop_velocity
    found = None if rates is None else _core.dormand_prince(rates, velocity, *arguments)
    if found is None:  # a kind, a law or a task of your own
        found = _core.dormand_prince(law.stage, velocity, *arguments)
    *accepted, failed, stopped, kept = found
    steps = Steps(law, first, *accepted)
    if not sparse:
        return on_grid(steps, grid, failed, stopped), steps
    # The samples: the starts, the ends of the accepted steps (in the records of the batches
    # the core's loop kept, at the positions of the steps it accepted, in the order it accepted
    # them) and the steps' midpoints, all taken from one batch of their records.
    middle, halfway, configurations = steps.midpoints()
    records = [start, *(record for record, _ in kept), law.evaluated(halfway, configurations)]
    offsets = np.cumsum([0] + [len(record[-1]) for record in records])  # q̇, or bad: (r, ...)
    ends = [positions + offsets[i + 1] for i, (_, positions) in enumerate(kept)]
    flat = np.concatenate([np.arange(k), *ends, offsets[-2] + np.arange(len(middle))])
    rows = np.concatenate([np.arange(k), steps.rows, middle])
    times = np.concatenate([np.zeros(k), steps.t0 + steps.h, halfway])
    samples = _assemble(
        k, rows, times, lambda index: law.rates(records, flat[index]), failed, stopped, None
    )
    return samples, steps


@dataclass(frozen=True, eq=False)
class Steps:
    """The accepted steps of an adaptive integration of ``law`` from the states whose rates
    are ``start`` (one per motion): step i of motion rows[i] went from t0[i] (s) and q0[i]
    (n,) over h[i] (s) with the stage slopes[i] (7, n), which give q anywhere within it by the
    dense output. Motions sampled sparsely are sampled on a grid from them without integrating
    or evaluating their starts again (`Trajectory.on_grid`)."""

    law: Law
    start: Rates
    rows: np.ndarray
    t0: np.ndarray
    h: np.ndarray
    q0: np.ndarray
    slopes: np.ndarray

    @classmethod
    def gathered(cls, law: Law, start: Rates, parts: list[tuple[np.ndarray, ...]]) -> Steps:
        """The steps of ``parts``, each (rows, t0, h, q0, slopes), as one record."""
        rows, t0, h, q0, slopes = (np.concatenate(part) for part in zip(*parts))
        return cls(law, start, rows, t0, h, q0, slopes)

    def select(self, rows: np.ndarray, count: int) -> Steps:
        """The steps of the motions ``rows`` (distinct indices among ``count``), numbered in
        that order."""
        number = np.full(count, -1)
        number[rows] = np.arange(len(rows))
        kept = number[self.rows] >= 0
        start = self.start.take(np.asarray(rows))
        return Steps(self.law, start, number[self.rows[kept]], *(a[kept] for a in self._arrays))

    @property
    def _arrays(self) -> tuple[np.ndarray, ...]:
        return self.t0, self.h, self.q0, self.slopes

    def joined(self, other: Steps, offset: int) -> Steps:
        """These steps and ``other``'s, whose motions are numbered from ``offset`` on."""
        return Steps.gathered(
            self.law,
            joined([self.start, other.start]),
            [(self.rows, *self._arrays), (other.rows + offset, *other._arrays)],
        )

    def dense(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The dense output at the times of ``grid`` (T,) in (t0, t0 + h] of each step: the
        rows, times and configurations of those samples."""
        reach = SAME_TIME * grid[-1]  # past a step's end, to rounding: the next step's start too
        first = np.searchsorted(grid, self.t0 + reach, side="right")
        last = np.searchsorted(grid, self.t0 + self.h + reach, side="right")
        counts = last - first
        owner = np.repeat(np.arange(len(self.rows)), counts)
        start = np.repeat(np.cumsum(counts) - counts, counts)
        times = grid[np.arange(counts.sum()) - start + first[owner]]
        return self.rows[owner], times, self._at(owner, (times - self.t0[owner]) / self.h[owner])

    def midpoints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The dense output at the middle of each step: rows, times and configurations."""
        every = np.arange(len(self.rows))
        return self.rows, self.t0 + self.h / 2, self._at(every, np.full(len(every), 0.5))

    def _at(self, owner: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """q at the fractions ``theta`` (p,) of the steps ``owner`` (p,): q0 + h Σ_s b_s(θ) K_s."""
        weights = np.stack([theta, theta**2, theta**3, theta**4], axis=1) @ DENSE.T  # (p, 7)
        increment = np.einsum("ps,psn->pn", weights, self.slopes[owner])
        return self.q0[owner] + self.h[owner, None] * increment


def on_grid(steps: Steps, grid: np.ndarray, failed, stopped):
    """The samples on ``grid`` (T,) of the motions that took ``steps`` (those ``failed`` or
    ``stopped`` stay where they ended): the law at their starts, as the integration began,
    and at the dense output, evaluated as one batch."""
    k, law = len(steps.start.bad), steps.law
    rows, times, q = steps.dense(grid)
    records = [steps.start, law.evaluated(times, q)]
    rows, times = np.concatenate([np.arange(k), rows]), np.concatenate([np.zeros(k), times])
    return _assemble(k, rows, times, partial(law.rates, records), failed, stopped, grid)


def joined(parts: list[Rates]) -> Rates:
    """The rates of several batches as one, in order."""
    return Rates(
        np.concatenate([part.x_dot for part in parts]),
        ActuatorSpace.joined([part.space for part in parts]),
        join([part.measure for part in parts]),
        np.concatenate([part.bad for part in parts]),
    )


def _assemble(k, rows, times, rates_at, failed, stopped, grid) -> dict:
    """The `Trajectory` fields of the samples of k motions at ``rows`` (p,) and ``times`` (p,),
    in time order per motion, padded by repeating each motion's last sample; on a ``grid``, a
    motion frozen early stays at rest over the grid's remaining times. ``rates_at(index)`` gives
    the `Rates` of the samples ``index`` (indices into rows and times): the states come as one
    flat batch of k·T, motion by motion."""
    order = np.lexsort((times, rows))
    counts = np.bincount(rows, minlength=k)
    length = counts.max() if grid is None else len(grid)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    index = order[start[:, None] + np.minimum(np.arange(length)[None], counts[:, None] - 1)]
    padded = np.arange(length)[None] >= counts[:, None]

    rates = rates_at(index.ravel())
    x_dot, measure, space = rates.x_dot.reshape(k, length, -1), rates.measure, rates.space
    t = times[index]
    if grid is not None:
        t = np.broadcast_to(grid, (k, length)).copy()
        x_dot[padded] = 0.0
        space = space.moving(np.where(padded.reshape(-1, 1), 0.0, rates.q_dot))
        if measure is not None:
            measure[padded.ravel()] = 0.0
    measure = None if measure is None else measure.reshape(k, length)
    return dict(t=t, space=space, x_dot=x_dot, failed=failed, stopped=stopped, measure=measure)
