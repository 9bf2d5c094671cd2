"""The strategies the improved method is compared with, each run from a fixed start on the same
robot and task: in the study, the baselines from the documented default start (`default_start`:
the held actuator at mid-stroke, or the reachable value nearest it); in the benchmarks, the plain
pseudoinverse, gradient projection with its gain tuning (benchmarks/peers.py) and pink's QP
differential IK (benchmarks/pink_peer.py), run from the same start.

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

from redundancy.errors import RedundancyError
from redundancy.model.hydraulics import BAR, KILOJOULE, LITRES_PER_MINUTE
from redundancy.model.robot import Robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, simulate
from redundancy.planning.starts import default_start, scalar_or_list
from redundancy.planning.tasks import Segment
from redundancy.planning.time_scaling import shortest_duration
from redundancy.resolution.laws import Resolver


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
    constant pressure (kJ), whether a load overran, the circuit's limits passed, the
    shortest duration of its path within the circuit's limits (s, `shortest_duration`; None
    where there is none, ``shortest_duration_reason`` saying why), whether the highest load
    pressure is one the relief valve never lets build (`Circuit.unphysical`), and the supplies
    that cannot serve the highest load pressure of a moving cylinder (``unserved``: its pump
    would run past what `Supply.available` gives under the relief, so its energy is no
    machine's)."""
    flows, circuit = motion.flows, motion.robot.circuit()
    violations = motion.hydraulic_violations(0)
    moving = np.where(flows.moving[0], flows.load[0], -np.inf).max(initial=-np.inf)
    shortest: float | None = None
    reason: str | None = None
    try:
        shortest = shortest_duration(motion).duration
    except RedundancyError as error:
        reason = str(error)
    return {
        "peak_pump_flow_l_min": float(flows.pump_flow[0].max() / LITRES_PER_MINUTE),
        "max_load_pressure_bar": float(flows.load[0].max() / BAR),
        **pump_energies(motion),
        "overrunning": bool(flows.overrunning[0].any()),
        "within_limits": not violations,
        "violations": [str(v) for v in violations],
        "shortest_duration_s": shortest,
        "shortest_duration_reason": reason,
        "unphysical": circuit.unphysical(float(flows.load[0].max())),
        "unserved": [
            supply.name for supply in circuit.supplies if moving > supply.available(circuit.relief)
        ],
    }


def pump_energies(motion: Trajectory) -> dict[str, float]:
    """The pump energy of the first motion of ``motion`` under load sensing and constant
    pressure (`Trajectory.energy`), kJ: ``{"ls_energy_kj", "cp_energy_kj"}``."""
    circuit = motion.robot.circuit()
    supplies = {"ls_energy_kj": circuit.load_sensing, "cp_energy_kj": circuit.constant_pressure}
    return {key: float(motion.energy(supply)[0] / KILOJOULE) for key, supply in supplies.items()}


def fixed_start_run(
    robot: Robot,
    resolver: Resolver,
    name: str,
    segment: Segment,
    held: str | Sequence[str] | None = None,
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
