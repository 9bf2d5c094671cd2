"""How many states the one Pinocchio pass evaluates, against how many distinct ones."""

from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

import redundancy.model.robot


@dataclass
class Evaluations:
    """States through the one pass (``evaluated``) and the distinct configurations among them."""

    evaluated: int = 0
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
    """Count every state `Robot.kinematics` sends through the pass while the block runs."""
    counts = Evaluations()
    track = redundancy.model.robot.track

    def counted(tracking, q, v=None):
        counts.evaluated += len(q)
        counts.seen.update(row.tobytes() for row in np.ascontiguousarray(q))
        return track(tracking, q, v)

    redundancy.model.robot.track = counted
    try:
        yield counts
    finally:
        redundancy.model.robot.track = track
