"""Tasks: straight segments travelled at constant speed (Eqs. 33-34) and work cycles of them.

A task file (TOML) names its points in task coordinates and the segments between them::

    name = "paper work cycle"
    speed = 0.5                       # m/s on every segment
    segments = ["1-2", "2-3", "3-1"]  # "<from>-<to>" by point name
    held = ["x3"]                     # actuators the improved search holds (optional)
    [points]
    1 = [3.5, -0.5]                   # one value per task axis of the robot, m
    2 = [1.0, -0.5]
    3 = [2.25, 3.0]
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError


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
        try:
            with path.open("rb") as f:
                data = tomllib.load(f)
        except (OSError, tomllib.TOMLDecodeError) as error:
            raise InvalidInputError(f"{path}: not a readable task file: {error}") from error
        points = data.get("points")
        if not isinstance(points, dict) or not points:
            raise InvalidInputError(f"{path}: needs a [points] table of name = [coordinates]")
        for name, value in points.items():
            if dimension is not None and np.shape(value) != (dimension,):
                raise InvalidInputError(
                    f"{path}: point {name} has {np.size(value)} coordinates; the robot's task "
                    f"has {dimension}"
                )
        segments = []
        for label in data.get("segments", []):
            ends = str(label).split("-")
            if len(ends) != 2 or any(e not in points for e in ends):
                raise InvalidInputError(
                    f"{path}: segment {label!r} must be '<from>-<to>' with points among "
                    f"{', '.join(points)}"
                )
            start, end = (np.asarray(points[e], dtype=float) for e in ends)
            segments.append(Segment(str(label), start, end, float(data.get("speed", 0.5))))
        if not segments:
            raise InvalidInputError(f"{path}: no segments")
        return cls(str(data.get("name", path.stem)), tuple(segments), tuple(data.get("held", ())))
