"""Time scaling: the shortest duration of a resolved path within the hydraulic circuit's limits.

A strategy's motion fixes a geometric path; how fast it can be run is a separate question. The
path is taken as the cylinders' strokes x(s) and the pumped volume V(s), s ∈ [0, 1] the motion's
normalised time, V the oil the pump has delivered (dV = Σ A_A dx where a cylinder extends,
A_B |dx| where it retracts, `redundancy.model.hydraulics`). Along a re-timed path s(t)

    |ẋ_i| = |x_i'| ṡ ≤ v_max,i,   |ẍ_i| = |x_i'' ṡ² + x_i' s̈| ≤ a_max,i,   Q_P = V' ṡ ≤ Q_max,

so the pump's flow is a velocity limit on the coordinate V. TOPP-RA (Pham & Pham, IEEE T-RO
34(3), 2018; the ``toppra`` package) finds the fastest s(t) from rest to rest, with constant s̈
between its grid points. A path along which an actuator the circuit does not limit (a slew)
moves while every cylinder stands still has no shortest duration: nothing bounds its speed
there. The limits hold at its grid points; where the dense re-timed samples
pass one by a hair, the timing is stretched uniformly by the least factor k that brings it back
(velocities scale by 1/k, accelerations by 1/k²). Actuators that are not cylinders are left
unconstrained.

Corners. Where the task's path turns at once (a polyline's inner point, or a cycle's corner
between segments: the `corners` among the path's breaks), the strokes' path turns too: its
tangent x' jumps from x'(s_c⁻) to x'(s_c⁺). Across the corner ẋ = x' ṡ jumps by
(x'(s_c⁺) − x'(s_c⁻)) ṡ, which no finite acceleration delivers unless ṡ(s_c) = 0: the tool
stops there. The fastest timing of such a path is therefore the fastest timing of each piece
between corners from rest to rest, one after the other,

    t_min = Σ_k T_k,   T_k the shortest duration of piece k with ṡ = 0 at both its ends,

each piece timed along its own samples (a spline through them that does not cross a corner).
The stroke at a corner the samples miss is read from the samples either side,
x(t_c) ≈ x_i + ẋ_i δ + ẍ_i δ²/2 with δ = t_c − t_i from the nearest one on each side, the two
averaged (each is O(δ³) off); a sample closer to a corner than half the spacing of the samples
TOPP-RA is given is replaced by it, so that no spline knot sits a hair from another. Where the
path does not turn at a break (where a speed profile's ramp ends, where a polyline's points lie
on one line), ẋ is continuous, and the piece goes on through it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from redundancy.errors import InvalidInputError, RedundancyError
from redundancy.model.robot import Robot
from redundancy.model.values import is_whole
from redundancy.planning.integrate import FAILED, Trajectory
from redundancy.planning.tasks import corners

SAMPLES = 400  # path points fed to TOPP-RA (at most; fewer if the motion has fewer), corners
# aside
STILL = 1e-9  # m: a cylinder whose stroke changes less than this between samples stands still
ALONE = 0.01  # of a motion's duration: a stretch this long where the cylinders stand still while
# another actuator moves the tool leaves its speed unbounded


@dataclass(frozen=True)
class Retimed:
    """The fastest timing of one motion's path: its ``duration`` (s), and the re-timed strokes
    x, velocities ẋ and accelerations ẍ of the cylinders (T, c) with the pump flow Q_P (T,) from
    those velocities, at times t (T,)."""

    duration: float
    t: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    pump_flow: np.ndarray

    def usage(self, robot: Robot) -> dict[str, float]:
        """The largest share of each limit the re-timed motion uses (1 = at the limit):
        "speed", "acceleration" and "pump flow"."""
        circuit = robot.circuit()
        return {
            "speed": float((np.abs(self.x_dot) / circuit.max_speeds).max()),
            "acceleration": float((np.abs(self.x_ddot) / circuit.max_accelerations).max()),
            "pump flow": float(self.pump_flow.max() / circuit.pump_flow),
        }


def pumped_volume(robot: Robot, x: np.ndarray) -> np.ndarray:
    """V (T,) m³, the oil delivered along strokes x (T, n) of all actuators, from V = 0."""
    circuit = robot.circuit()
    oil = circuit.cylinder_flows(np.diff(x[:, circuit.columns], axis=0)).sum(axis=1)
    return np.concatenate([[0.0], np.cumsum(oil)])


def shortest_duration(motion: Trajectory, row: int = 0, samples: int = SAMPLES) -> Retimed:
    """The fastest timing, from rest to rest and at rest at each of its path's `corners`, of
    the path of motion ``row`` within the cylinders' speeds and accelerations and the pump's
    flow (see the module docstring): the pieces between corners one after the other, each
    corner's sample twice in the result (the end of the piece before, at rest, and the start
    of the one after); a motion that failed has no path to time (`InvalidInputError`)."""
    if not is_whole(row, 0, len(motion.t) - 1):
        raise InvalidInputError(
            f"row must be one of the {len(motion.t)} motions' rows; got {row!r}"
        )
    if not is_whole(samples, 3):
        raise InvalidInputError(f"samples must be a whole number ≥ 3; got {samples!r}")
    if motion.failed[row]:
        raise InvalidInputError(
            f"motion {row} along segment {motion.segment.name} failed, {FAILED}: it has no "
            "path to time"
        )
    robot = motion.robot
    circuit = robot.circuit()  # says how to declare one before any work
    t = motion.t[row]
    last = int(motion.counts[row])  # a motion repeats its last sample to pad
    _require_bounded(motion, row, last, circuit.columns)
    chosen = np.unique(np.linspace(0, last - 1, min(samples, last)).round().astype(int))
    turns = corners(motion.segment)
    turns = turns[turns < t[last - 1]]  # a motion stopped early ends before some
    ends = np.concatenate([[0.0], turns, [t[last - 1]]])
    points = np.concatenate([[motion.x[row, 0]], _at_corners(motion, row, turns)])
    points = np.concatenate([points, [motion.x[row, last - 1]]])
    gap = 0.5 * float(np.median(np.diff(t[chosen]))) if turns.size else 0.0
    inner = chosen[(chosen > 0) & (chosen < last - 1)]
    near = np.abs(t[inner, None] - turns[None]).min(axis=1, initial=np.inf) < gap
    inner = inner[~near]
    timings = []
    for k in range(len(ends) - 1):
        within = inner[(t[inner] > ends[k]) & (t[inner] < ends[k + 1])]
        s = np.concatenate([[ends[k]], t[within], [ends[k + 1]]]) / t[last - 1]
        x = np.concatenate([points[k : k + 1], motion.x[row, within], points[k + 1 : k + 2]])
        timings.append(_fastest(robot, s, x, motion.segment.name))
    offsets = np.cumsum([0.0] + [timing.duration for timing in timings])
    return Retimed(
        float(offsets[-1]),
        np.concatenate([timing.t + offset for timing, offset in zip(timings, offsets)]),
        *(
            np.concatenate([getattr(timing, name) for timing in timings])
            for name in ("x", "x_dot", "x_ddot", "pump_flow")
        ),
    )


def _require_bounded(motion: Trajectory, row: int, last: int, cylinders) -> None:
    """Refuse a path whose speed no limit bounds: where every cylinder stands still (`STILL`
    between samples) while an actuator the circuit does not limit moves (a slew following an
    arc about its column), over a stretch of at least `ALONE` of the motion's duration, ṡ is
    bounded by nothing, and TOPP-RA's "fastest" timing is its grid's artefact. An instant where
    the cylinders turn back together (a slew's chord, whose radial speed passes through zero
    at its middle) is no such stretch: their accelerations bound the timing there."""
    steps = np.abs(np.diff(motion.x[row, :last], axis=0))
    others = np.setdiff1d(np.arange(steps.shape[1]), cylinders)
    still = steps[:, cylinders].max(axis=1, initial=0.0) <= STILL
    moving = steps[:, others].max(axis=1, initial=0.0) > STILL
    edges = np.diff(np.concatenate([[0], still & moving, [0]]).astype(int))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, end)
    t = motion.t[row]
    spans = t[ends] - t[starts]
    if spans.size and spans.max() >= ALONE * (t[last - 1] - t[0]):
        first = int(starts[np.argmax(spans)])
        names = motion.robot.actuators.names
        moved = sorted({names[j] for j in others if steps[first, j] > STILL})
        raise RedundancyError(
            f"unbounded: {', '.join(moved)} alone moves the tool from t = {t[first]:.2f} s to "
            f"{t[ends[np.argmax(spans)]]:.2f} s with every cylinder still, and the circuit "
            "limits only cylinders and the pump"
        )


def _at_corners(motion: Trajectory, row: int, turns: np.ndarray) -> np.ndarray:
    """The strokes x (c, n) of motion ``row`` at the corner times ``turns`` (c,): a sample's
    own where one lies within 1e-9 of the motion's duration of the corner; otherwise the mean
    of the two second-order Taylor steps, x_i + ẋ_i δ + ẍ_i δ²/2 with δ = t_c − t_i, from the
    nearest sample on each side (ẋ and ẍ of its own side of the corner)."""
    if not len(turns):
        return np.empty((0, motion.x.shape[2]))
    t = motion.t[row, : int(motion.counts[row])]
    x, rate, second = (values[row] for values in (motion.x, motion.x_dot, motion.x_ddot))
    out = np.empty((len(turns), x.shape[1]))
    for c, time in enumerate(turns):
        on = np.flatnonzero(np.abs(t - time) <= 1e-9 * t[-1])
        if on.size:
            out[c] = x[on[0]]
            continue
        after = int(np.searchsorted(t, time))
        steps = [
            x[i] + rate[i] * (time - t[i]) + second[i] * (time - t[i]) ** 2 / 2
            for i in (after - 1, after)
        ]
        out[c] = (steps[0] + steps[1]) / 2
    return out


def _fastest(robot: Robot, s: np.ndarray, x: np.ndarray, name: str) -> Retimed:
    """TOPP-RA's fastest timing from rest to rest of the path through the strokes x (p, n) at
    the path parameters s (p,), increasing (see the module docstring), stretched by the least
    k that keeps every limit at the dense re-timed samples."""
    import toppra  # its algorithms and constraints come with it

    circuit = robot.circuit()
    strokes = x[:, circuit.columns]
    volume = pumped_volume(robot, x)
    path = toppra.SplineInterpolator(s, np.column_stack([strokes, volume]))
    speeds = np.append(circuit.max_speeds, circuit.pump_flow)
    accelerations = np.append(circuit.max_accelerations, np.inf)
    velocity = toppra.constraint.JointVelocityConstraint(np.column_stack([-speeds, speeds]))
    acceleration = toppra.constraint.JointAccelerationConstraint(
        np.column_stack([-accelerations, accelerations])
    )
    instance = toppra.algorithm.TOPPRA(
        [velocity, acceleration],
        path,
        gridpoints=np.linspace(s[0], s[-1], 2 * len(s) + 1),
        parametrizer="ParametrizeConstAccel",
    )
    timing = instance.compute_trajectory(0, 0)
    if timing is None:
        raise RedundancyError(f"TOPP-RA found no timing of segment {name}'s path")
    times = np.linspace(0.0, timing.duration, 4 * len(s) + 1)
    c = len(circuit.columns)
    state, rate, second = (timing(times, order)[:, :c] for order in (0, 1, 2))
    retimed = Retimed(
        float(timing.duration), times, state, rate, second, circuit.cylinder_flows(rate).sum(1)
    )
    usage = retimed.usage(robot)
    k = max(1.0, usage["speed"], usage["pump flow"], np.sqrt(usage["acceleration"]))
    return Retimed(
        retimed.duration * k,
        times * k,
        state,
        rate / k,
        second / k**2,
        retimed.pump_flow / k,
    )
