"""The peers the improved method is measured against, run on the same robot and task.

- Plain pseudoinverse (Eq. 24) from the documented default start (`default_start`: the held
  actuator at mid-stroke, or the reachable value nearest it).
- Gradient projection with actuator-limit avoidance (Eq. 1, `GradientProjection`) from the same
  start, with its gain tuned on the paper's segments (`tune_gradient_projection`, `TUNED_GAIN`).

A QP-based differential IK as users of Pinocchio pick it, pink, is a peer of the benchmarks
(benchmarks/pink_peer.py), run from the same start.

Every run is a `StrategyRun` whose trajectory reports the strokes as they were: a peer that
leaves a limit is flagged by `Trajectory.within_limits` and `Trajectory.violations`, never
clipped.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from redundancy.errors import InvalidInputError, RedundancyError
from redundancy.model.hydraulics import BAR, KILOJOULE, LITRES_PER_MINUTE
from redundancy.model.robot import Robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, simulate
from redundancy.planning.starts import default_start, scalar_or_list
from redundancy.planning.tasks import Segment
from redundancy.planning.time_scaling import shortest_duration
from redundancy.resolution.laws import TUNED_GAIN, GradientProjection, MinVelocityNorm, Resolver

# The candidates `tune_gradient_projection` tried on the crane's paper segments (velocity
# objective, every stroke checked, default starts, 0.01 s steps) to choose `TUNED_GAIN`: the gain
# whose worst peak ẋᵀẋ over the three segments is least among those keeping every stroke inside
# its limits on all three. Smaller gains let x1 leave its stroke on segment 3-1; larger ones raise
# the peak at the start of segment 1-2, whose default start lies near the stroke ends.
GAINS = (0.02, 0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0)  # candidates, m²/s


@dataclass(frozen=True)
class StrategyRun:
    """One motion of one strategy along one segment."""

    segment: str
    strategy: str
    start: tuple[float, ...]
    trajectory: Trajectory

    def summary(self) -> dict:
        """The run's figures as JSON-ready data (a fresh copy each call)."""
        return copy.deepcopy(self._summary)

    @cached_property
    def _summary(self) -> dict:
        motion = self.trajectory
        return {
            "segment": self.segment,
            "strategy": self.strategy,
            "start_value": scalar_or_list(self.start),
            "peak_velocity_norm": float(motion.peak_velocity_norm[0]),
            "peak_kinetic": (  # undefined on a kinematic-only robot
                None if motion.robot.kinematic_only else float(motion.peak_kinetic[0])
            ),
            "within_limits": bool(motion.within_limits[0]),
            "max_tracking_error": float(motion.max_tracking_error[0]),
            "violations": [str(v) for v in motion.violations(0)],
            **({} if motion.robot.hydraulics is None else {"hydraulics": hydraulics(motion)}),
        }


def hydraulics(motion: Trajectory) -> dict:
    """The hydraulic figures of the first motion of ``motion`` in the units the field uses:
    peak pump flow (L/min), highest load pressure (bar), pump energy under load sensing and
    constant pressure (kJ), whether a load overran, the circuit's limits passed, and the
    shortest duration of its path within the circuit's limits (s, `shortest_duration`; None
    where TOPP-RA finds no timing)."""
    circuit, flows = motion.robot.circuit(), motion.flows
    violations = motion.hydraulic_violations(0)
    try:
        shortest: float | None = shortest_duration(motion).duration
    except RedundancyError:
        shortest = None
    return {
        "peak_pump_flow_l_min": float(flows.pump_flow[0].max() / LITRES_PER_MINUTE),
        "max_load_pressure_bar": float(flows.load[0].max() / BAR),
        "ls_energy_kj": float(motion.energy(circuit.load_sensing)[0] / KILOJOULE),
        "cp_energy_kj": float(motion.energy(circuit.constant_pressure)[0] / KILOJOULE),
        "overrunning": bool(flows.overrunning[0].any()),
        "within_limits": not violations,
        "violations": [str(v) for v in violations],
        "shortest_duration_s": shortest,
    }


def fixed_start_run(
    robot: Robot,
    resolver: Resolver,
    name: str,
    segment: Segment,
    held: str | Sequence[str] = "x3",
    start: tuple[np.ndarray, np.ndarray] | None = None,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    method: str = "adaptive",
    circuit: bool = False,
) -> StrategyRun:
    """``resolver`` along ``segment`` from a fixed start: ``start`` = (held values (r,), q (n,)),
    by default `default_start`; the run is called ``name``. With ``circuit`` the hydraulic
    circuit's limits count for its `within_limits` too."""
    values, q = default_start(robot, segment, held) if start is None else start
    motion = simulate(
        robot,
        resolver,
        segment,
        q[None],
        time_step,
        checked=checked,
        method=method,
        circuit=circuit,
    )
    return StrategyRun(segment.name, name, tuple(float(v) for v in values), motion)


def pseudoinverse_run(
    robot: Robot,
    segment: Segment,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
) -> StrategyRun:
    """ẋ = J_H⁺ ẏ (Eq. 24) along ``segment`` from the default start."""
    return fixed_start_run(
        robot, MinVelocityNorm(), "pseudoinverse", segment, held, None, checked, time_step, "rk4"
    )


def gradient_projection_run(
    robot: Robot,
    segment: Segment,
    gain: float = TUNED_GAIN,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
) -> StrategyRun:
    """Gradient projection with actuator-limit avoidance, gain α (m²/s), from the default start."""
    name = f"gradient projection (α = {gain:g} m²/s)"
    resolver = GradientProjection(gain)
    return fixed_start_run(robot, resolver, name, segment, held, None, checked, time_step, "rk4")


@dataclass(frozen=True)
class GainTuning:
    """Gradient projection over candidate gains (g,) on segments (s,): the peaks ẋᵀẋ (g, s)
    in m²/s², whether every checked stroke held (g, s), and the chosen gain (None if none kept
    every limit on every segment)."""

    gains: tuple[float, ...]
    segments: tuple[str, ...]
    peaks: np.ndarray
    within: np.ndarray
    chosen: float | None


def tune_gradient_projection(
    robot: Robot,
    segments: tuple[Segment, ...],
    gains: tuple[float, ...] = GAINS,
    held: str = "x3",
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
) -> GainTuning:
    """The gain (m²/s) of least worst peak ẋᵀẋ over ``segments`` among ``gains`` keeping every
    checked stroke inside its limits on all of them, each run from the default start."""
    if not gains or any(not g > 0 for g in gains):
        raise InvalidInputError(f"gains must be positive numbers, m²/s; got {gains}")
    runs = [
        [gradient_projection_run(robot, s, g, held, checked, time_step) for s in segments]
        for g in gains
    ]
    peaks = np.array([[r.trajectory.peak_velocity_norm[0] for r in row] for row in runs])
    within = np.array([[bool(r.trajectory.within_limits[0]) for r in row] for row in runs])
    keeping = np.flatnonzero(within.all(axis=1))
    chosen = float(gains[keeping[np.argmin(peaks[keeping].max(axis=1))]]) if keeping.size else None
    return GainTuning(tuple(gains), tuple(s.name for s in segments), peaks, within, chosen)
