"""Tasks: straight segments travelled at constant speed (Eqs. 33-34) and work cycles of them.

A task file (TOML) names its points in task coordinates and the segments between them::

    name = "paper work cycle"
    speed = 0.5                       # m/s on every segment (at most 10)
    segments = ["1-2", "2-3", "3-1"]  # "<from>-<to>" by point name
    held = ["x3"]                     # actuators the improved search holds (optional)
    [points]
    1 = [3.5, -0.5]                   # one value per task axis of the robot, m
    2 = [1.0, -0.5]
    3 = [2.25, 3.0]
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.values import MAX_SPEED, coordinates, names, number, read_toml, text


@dataclass(frozen=True)
class Segment:
    """The straight line P→Q travelled uniformly at ``speed`` m/s; P, Q of shape (m,), in m."""

    name: str
    start: np.ndarray
    end: np.ndarray
    speed: float

    def __post_init__(self) -> None:
        if not np.all(np.isfinite(self.start)) or not np.all(np.isfinite(self.end)):
            raise InvalidInputError(f"segment {self.name}: points must be finite")
        if np.shape(self.start) != np.shape(self.end):
            raise InvalidInputError(f"segment {self.name}: start and end differ in dimension")
        if not self.speed > 0:
            raise InvalidInputError(f"segment {self.name}: speed must be > 0 m/s")
        if not np.linalg.norm(self.end - self.start) > 0:
            raise InvalidInputError(f"segment {self.name}: start and end coincide")

    @cached_property
    def duration(self) -> float:
        """t_f = |Q − P| / speed, in s."""
        return float(np.linalg.norm(self.end - self.start) / self.speed)

    @cached_property
    def velocity(self) -> np.ndarray:
        """ẏ_d = (Q − P) / t_f (Eq. 34), constant, (m,) in m/s (read-only)."""
        velocity = (self.end - self.start) / self.duration
        velocity.setflags(write=False)
        return velocity

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """y_d(t) = Q + (1 − t/t_f)(P − Q) (Eq. 33), (..., m) for t (...,) in s."""
        s = np.asarray(t, dtype=float)[..., None] / self.duration
        return self.end + (1 - s) * (self.start - self.end)


@dataclass(frozen=True)
class WorkCycle:
    """Segments travelled one after another, and the actuators a search holds."""

    name: str
    segments: tuple[Segment, ...]
    held: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> Segment:
        for segment in self.segments:
            if segment.name == name:
                return segment
        names = ", ".join(s.name for s in self.segments)
        raise InvalidInputError(f"no segment {name!r} in {self.name!r}; segments: {names}")

    @classmethod
    def from_toml(cls, path: Path | str, dimension: int | None = None) -> WorkCycle:
        """Read a task file; ``dimension`` (the robot's m) checks every point's size."""
        path = Path(path)
        data = read_toml(path, "task file")
        where = str(path)
        points = data.get("points")
        if not isinstance(points, dict) or not points:
            raise InvalidInputError(f"{path}: needs a [points] table of name = [coordinates]")
        found = {
            name: coordinates(value, f"{where}: point {name}", dimension)
            for name, value in points.items()
        }
        speed = number(data, "speed", where, "m/s on every segment", 0.5, 0.0, MAX_SPEED)
        segments = []
        for label in names(data, "segments", where, "'<from>-<to>' by point name"):
            ends = label.split("-")
            if len(ends) != 2 or any(e not in found for e in ends):
                raise InvalidInputError(
                    f"{path}: segment {label!r} must be '<from>-<to>' with points among "
                    f"{', '.join(found)}"
                )
            segments.append(Segment(label, found[ends[0]], found[ends[1]], speed))
        if not segments:
            raise InvalidInputError(f"{path}: no segments")
        held = names(data, "held", where, "the actuators the improved search holds")
        return cls(text(data, "name", where, "the task's name", path.stem), tuple(segments), held)
