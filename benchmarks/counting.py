"""How many states the one Pinocchio pass evaluates, against how many distinct ones."""

from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

import redundancy.model.robot
import redundancy.planning.integrate
import redundancy.resolution.state
from redundancy.model.kinematics import Kinematics
from redundancy.model.robot import Robot


@dataclass
class Evaluations:
    """States through the one pass (``evaluated``) and the distinct configurations among them;
    ``moving``: states passed again at their joint velocities for their rates (Ȧ), counted
    apart since the compiled pass reruns at the same q rather than derive them."""

    evaluated: int = 0
    moving: int = 0
    seen: set[bytes] = field(default_factory=set)

    @property
    def distinct(self) -> int:
        return len(self.seen)

    @property
    def ratio(self) -> float:
        """Evaluated per distinct state: 1 when nothing is evaluated twice."""
        return self.evaluated / max(self.distinct, 1)


@contextmanager
def counting():
    """Count every state `Robot.kinematics` or the compiled evaluation (`Robot.evaluator`)
    sends through the pass while the block runs, and every state `Kinematics.moving` passes
    again. The core's integration loop evaluates its stages in C++, out of sight: within the
    block it runs on the law's Python right-hand side instead (`Law.stage`), which evaluates
    the same states, one call per stage; so does the core's Newton loop, on the Python pass of
    the task and the held actuators instead of `Robot.held_pass`."""
    counts = Evaluations()
    state, integrate = redundancy.resolution.state, redundancy.planning.integrate
    track, compiled, moving = redundancy.model.robot.track, state._compiled, Kinematics.moving
    rates, held = integrate.compiled_rates, Robot.held_pass

    def seen(q):
        counts.evaluated += len(q)
        counts.seen.update(row.tobytes() for row in np.ascontiguousarray(q))

    def counted(tracking, q, v=None):
        seen(q)
        return track(tracking, q, v)

    def counted_compiled(robot, q, v, finite):
        space = compiled(robot, q, v, finite)
        if space is not None:
            seen(space.q)
        return space

    def counted_moving(kinematics, v):
        counts.moving += len(v)
        return moving(kinematics, v)

    redundancy.model.robot.track = counted
    state._compiled = counted_compiled
    Kinematics.moving = counted_moving  # type: ignore[method-assign]
    integrate.compiled_rates = lambda robot, law: None
    Robot.held_pass = lambda robot, part: None  # type: ignore[method-assign]
    try:
        yield counts
    finally:
        redundancy.model.robot.track = track
        state._compiled = compiled
        Kinematics.moving = moving  # type: ignore[method-assign]
        integrate.compiled_rates = rates
        Robot.held_pass = held  # type: ignore[method-assign]
