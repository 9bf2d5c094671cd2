"""The resolver peers of the benchmarks and tests, run on the same robot and task as the study:

- the plain pseudoinverse (Eq. 24) from the documented default start (`default_start`: the
  held actuator at mid-stroke, or the reachable value nearest it);
- gradient projection with actuator-limit avoidance (Eq. 1, `GradientProjection`) from the same
  start, and the tuning of its gain on the paper's segments (`tune_gradient_projection`), which
  chose `TUNED_GAIN`.

Each run is a `StrategyRun` (`redundancy.study.peers.fixed_start_run`) whose trajectory reports
the strokes as they were: a peer that leaves a limit is flagged, never clipped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.robot import Robot
from redundancy.planning.integrate import TIME_STEP
from redundancy.planning.tasks import Segment
from redundancy.resolution.laws import TUNED_GAIN, GradientProjection, MinVelocityNorm
from redundancy.study.peers import StrategyRun, fixed_start_run

# The candidates `tune_gradient_projection` tried on the crane's paper segments (velocity
# objective, every stroke checked, default starts, 0.01 s steps) to choose `TUNED_GAIN`: the gain
# whose worst peak ẋᵀẋ over the three segments is least among those keeping every stroke inside
# its limits on all three. Smaller gains let x1 leave its stroke on segment 3-1; larger ones raise
# the peak at the start of segment 1-2, whose default start lies near the stroke ends.
GAINS = (0.02, 0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0)  # candidates, m²/s


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
