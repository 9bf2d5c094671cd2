"""Tasks: paths in task coordinates, how fast they are travelled, and work cycles of them.

A segment is a path and a speed profile. Paths (`Line`, `Arc`, `Polyline`) are parametrised by
the arc length s ∈ [0, length] of the tool's position: a straight line P→Q (Eq. 33), a circular
arc (through a third point, or about a centre; a closed circle ends where it starts) or a
polyline through recorded points (a CSV file). Where the task's last coordinate is the tool's
angle, it changes linearly with s (a closed circle keeps it); speeds are the position's.
Speed profiles: "constant", ṡ = speed from t = 0 (Eq. 34), so ẏ jumps at a cycle's
corners; or "trapezoidal", from rest to rest at most ``acceleration``, ẏ continuous.

A work cycle is a `Chain` of segments, one path over time; a cycle a machine repeats is
continuous and closed (`WorkCycle.check_continuous`). The task file (`WorkCycle.from_toml`) and
the CSV polyline (`read_polyline`) are documented key by key in docs/machines.md.
"""

from __future__ import annotations

import csv
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError, prefixed
from redundancy.model.schema import (
    SegmentTable,
    TaskFile,
    excerpt,
    read_text,
    read_toml,
    toml,
    validate,
)
from redundancy.model.values import MAX_ACCELERATION, MAX_SPEED, decimal, is_real

PROFILES = ("constant", "trapezoidal")
DIRECTIONS = ("ccw", "cw")
CLOSED = 1e-9  # m (or rad): ends this close count as one point
MAX_COORDINATE = 1000.0  # m, or degrees for the tool's angle: a task file's points lie within
# this of the robot's base, as far as any manipulator's workspace with room to spare
MAX_DURATION = 600.0  # s a segment may take: a work cycle's moves take seconds to a minute, and
# a motion on the 10 ms grid holds 60,000 samples at this
ARC_MISMATCH = 1e-6  # relative: an arc's ends must lie this close to one circle about its centre
OUTLINE = 64  # points per full turn when a curved path is drawn
TIMING = ("speed", "profile", "acceleration")  # the keys a task file and a segment's table share
ARC_KEYS = ("from", "to", "via", "centre", "center", "direction")  # a line's or an arc's keys
SAME_TIME = 1e-12  # of the duration: times closer are one (breaks, as the core's steps take them;
# a grid time and a step's end in the dense output)
PROBE = 1e-9  # of the time to a break's nearest neighbour: how far either side ẏ_d is read
JUMP = 1e-6  # of the path's peak speed: a smaller change of ẏ_d across a break is none (a ramp's
# end, a corner where the path comes to rest)
TURN = 1e-6  # rad: ẏ_d's directions either side of a break closer than this are one (round-off
# in a recorded polyline's points on one line, a curve's own turn over the `PROBE`)


def finite_vector(value: object) -> np.ndarray | None:
    """``value`` as a vector (k,) of finite floats, k ≥ 1, or None where it is none."""
    try:
        vector = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return vector if vector.ndim == 1 and vector.size and np.isfinite(vector).all() else None


def _piece(edges: np.ndarray, x) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (...,) as floats and the piece i of each, edges[i] ≤ x < edges[i + 1], the first
    and last pieces extended beyond the ends."""
    x = np.asarray(x, dtype=float)
    return x, np.searchsorted(edges[1:-1], x, side="right")  # inner edges at or below x


class Shape(ABC):
    """Geometry of a segment in task coordinates (m of them; the last ``angles`` are angles),
    parametrised by the arc length s ∈ [0, length] (m) of the position (the first m − angles):
    ``point(s)`` y (..., m) and ``tangent(s)`` dy/ds (..., m), a unit vector in the position
    and the angle's rate per metre, for s (...,); ``outline()`` points (P, m) that draw it."""

    start: np.ndarray
    end: np.ndarray
    angles: int
    kind: str = "path"

    @property
    @abstractmethod
    def length(self) -> float: ...

    @abstractmethod
    def point(self, s: np.ndarray) -> np.ndarray: ...

    @abstractmethod
    def tangent(self, s: np.ndarray) -> np.ndarray: ...

    @abstractmethod
    def outline(self) -> np.ndarray: ...


def _position(y: np.ndarray, angles: int) -> np.ndarray:
    return y[: len(y) - angles]


@dataclass(frozen=True)
class Polyline(Shape):
    """Straight pieces through ``points`` (K, m), K ≥ 2, consecutive ones at distinct
    positions; beyond its ends it goes on along its first and last pieces."""

    points: np.ndarray
    angles: int = 0
    kind = "polyline"

    def __post_init__(self) -> None:
        try:
            points = np.asarray(self.points, dtype=float)
        except (TypeError, ValueError):  # not numbers, or rows of unequal length
            points = np.empty(0)
        if points.ndim != 2 or not np.isfinite(points).all():
            raise InvalidInputError(
                f"a polyline's points must be (K, m) finite numbers; got {excerpt(self.points)}"
            )
        object.__setattr__(self, "points", points)
        if len(self.points) < 2:
            raise InvalidInputError("a polyline needs at least two points")
        if not np.all(np.diff(self.cumulative) > CLOSED):
            what = "start and end" if self.kind == "line" else "consecutive points of a polyline"
            raise InvalidInputError(f"{what} coincide in position (closer than {CLOSED:g} m)")

    @property
    def start(self) -> np.ndarray:  # type: ignore[override]
        return self.points[0]

    @property
    def end(self) -> np.ndarray:  # type: ignore[override]
        return self.points[-1]

    @cached_property
    def cumulative(self) -> np.ndarray:
        """Arc length at each point, (K,)."""
        p = self.points.shape[1] - self.angles
        legs = np.linalg.norm(np.diff(self.points[:, :p], axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(legs)])

    @cached_property
    def slopes(self) -> np.ndarray:
        """dy/ds along each piece, (K − 1, m)."""
        return np.diff(self.points, axis=0) / np.diff(self.cumulative)[:, None]

    @property
    def length(self) -> float:
        return float(self.cumulative[-1])

    @property
    def kinks(self) -> tuple[float, ...]:
        """Arc lengths inside the path where its tangent jumps."""
        return tuple(float(s) for s in self.cumulative[1:-1])

    def point(self, s):
        s, leg = _piece(self.cumulative, s)
        return self.points[leg] + (s - self.cumulative[leg])[..., None] * self.slopes[leg]

    def tangent(self, s):
        return self.slopes[_piece(self.cumulative, s)[1]]

    def outline(self) -> np.ndarray:
        return self.points


class Line(Polyline):
    """The straight line from ``start`` to ``end`` (m,) (Eq. 33): y(s) = P + s (Q − P) / |Q − P|
    in the position."""

    kind = "line"

    def __init__(self, start: np.ndarray, end: np.ndarray, angles: int = 0) -> None:
        super().__init__(np.array([start, end], dtype=float), angles)


@dataclass(frozen=True)
class Arc(Shape):
    """A circular arc: centre c (p,), orthonormal e1, e2 (p,) spanning its plane, ``radius`` R
    and ``sweep`` θ > 0 (rad): the position c + R (cos φ e1 + sin φ e2), φ = s / R ∈ [0, θ],
    from ``start`` to ``end`` (m,). Built by `Arc.through` or `Arc.about`."""

    start: np.ndarray
    end: np.ndarray
    centre: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    radius: float
    sweep: float
    angles: int = 0
    kind = "arc"

    @property
    def closed(self) -> bool:
        return self.sweep >= 2 * math.pi - 1e-12

    @property
    def length(self) -> float:
        return self.radius * self.sweep

    @cached_property
    def rate(self) -> np.ndarray:
        """The angle coordinates' change per metre, (angles,)."""
        return (self.end - self.start)[len(self.centre) :] / self.length

    def point(self, s):
        s = np.asarray(s, dtype=float)[..., None]
        phi = s / self.radius
        position = self.centre + self.radius * (np.cos(phi) * self.e1 + np.sin(phi) * self.e2)
        return np.concatenate([position, self.start[len(self.centre) :] + s * self.rate], -1)

    def tangent(self, s):
        phi = np.asarray(s, dtype=float)[..., None] / self.radius
        direction = -np.sin(phi) * self.e1 + np.cos(phi) * self.e2
        rate = np.broadcast_to(self.rate, (*phi.shape[:-1], self.angles))
        return np.concatenate([direction, rate], axis=-1)

    def outline(self) -> np.ndarray:
        count = max(8, int(OUTLINE * self.sweep / (2 * math.pi)) + 1)
        return self.point(np.linspace(0.0, self.length, count))

    @classmethod
    def through(cls, start, via, end, angles: int = 0) -> Arc:
        """The arc from ``start`` through ``via`` to ``end`` (m,) each, in any dimension ≥ 2."""
        a, b, c = (_position(np.asarray(v, dtype=float), angles) for v in (start, via, end))
        u, v = b - a, c - a
        uu, vv, uv = u @ u, v @ v, u @ v
        determinant = uu * vv - uv * uv
        if len(a) < 2 or determinant <= 1e-12 * max(uu * vv, 1e-300):
            raise InvalidInputError("its three points lie on one line (or coincide)")
        centre = a + (vv * (uu - uv) * u + uu * (vv - uv) * v) / (2 * determinant)
        radius = float(np.linalg.norm(a - centre))
        e1 = (a - centre) / radius
        side = (b - centre) - ((b - centre) @ e1) * e1
        e2 = side / np.linalg.norm(side)  # the via point lies at an angle in (0, π] or beyond
        if _angle_of(b - centre, e1, e2) > _angle_of(c - centre, e1, e2):
            e2 = -e2  # via beyond the end: go round the other way
        sweep = _angle_of(c - centre, e1, e2)
        start, end = np.asarray(start, float), np.asarray(end, float)
        return cls(start, end, centre, e1, e2, radius, sweep, angles)

    @classmethod
    def about(cls, start, end, centre, direction: str, angles: int = 0) -> Arc:
        """The arc about ``centre`` (p,) from ``start`` to ``end`` (m,) in ``direction`` ("ccw":
        from the first position axis towards the second; "cw"); a full circle where they meet.
        The position must be planar (p = 2)."""
        start, end = np.asarray(start, float), np.asarray(end, float)
        a, c = _position(start, angles), _position(end, angles)
        centre = np.asarray(centre, dtype=float)
        if len(a) != 2:
            raise InvalidInputError(
                f"an arc about a centre needs a planar position (2 task axes); this task has "
                f"{len(a)}: give a third point with via instead"
            )
        if direction not in DIRECTIONS:
            raise InvalidInputError(
                f"direction = {direction!r} must be one of {', '.join(DIRECTIONS)}"
            )
        radius, far = float(np.linalg.norm(a - centre)), float(np.linalg.norm(c - centre))
        if not radius > CLOSED:
            raise InvalidInputError(f"its start lies on its centre (closer than {CLOSED:g} m)")
        if abs(far - radius) > ARC_MISMATCH * radius:
            raise InvalidInputError(
                f"its ends lie {radius:.6g} m and {far:.6g} m from the centre; an arc's ends lie "
                "at one distance"
            )
        e1 = (a - centre) / radius
        e2 = np.array([-e1[1], e1[0]]) * (1 if direction == "ccw" else -1)
        sweep = _angle_of(c - centre, e1, e2)
        if sweep < 1e-12 or np.linalg.norm(c - a) <= CLOSED:
            sweep = 2 * math.pi
            if np.any(np.abs(end - start) > CLOSED):
                raise InvalidInputError("a closed circle ends where it starts, its angle too")
        return cls(start, end, centre, e1, e2, radius, sweep, angles)


NAME_BYTES = 100  # a segment name's most, in UTF-8: its outputs' names add up to 30 more, of 255


def _file_part(name: str) -> bool:
    """Whether ``name`` can stand in a file's name as it is: a segment's outputs are named
    after it, so no path separator may lead them out of their folder, and their names must fit
    a file system's 255 bytes."""
    return (
        name not in ("", ".", "..")
        and name.isprintable()
        and not set(name) & {"/", "\\"}
        and len(name.encode()) <= NAME_BYTES
    )


def _angle_of(d: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> float:
    """The angle of d in the plane (e1, e2), in [0, 2π)."""
    angle = math.atan2(float(d @ e2), float(d @ e1))
    return angle + 2 * math.pi if angle < -1e-12 else max(angle, 0.0)


@dataclass(frozen=True)
class Segment:
    """A path from ``start`` to ``end`` (m,) travelled at ``speed`` m/s with a speed
    ``profile``: "constant" (Eq. 34), or "trapezoidal" from rest to rest with at most
    ``acceleration`` m/s². By default the straight line P→Q at constant speed (Eqs. 33-34);
    `Segment.along` builds any path and profile."""

    name: str
    start: np.ndarray
    end: np.ndarray
    speed: float
    shape: Shape = field(default=None, repr=False)  # type: ignore[assignment]  # None: a line
    profile: str = "constant"
    acceleration: float | None = None
    source: str = field(default="", compare=False, repr=False)  # its task file's entry, if read
    held: tuple[str, ...] = field(default=(), compare=False, repr=False)  # its task's, if read

    def __post_init__(self) -> None:
        name = self.name
        if not isinstance(name, str) or not _file_part(name):
            raise InvalidInputError(
                f"segment name {excerpt(name)} must be text that can be part of a file's "
                f"name (the outputs are named after it): at most {NAME_BYTES} bytes, not empty, "
                "'.' or '..', and without '/', '\\' or unprintable characters"
            )
        with prefixed(f"segment {self.name}"):
            for end in ("start", "end"):
                point = finite_vector(getattr(self, end))
                if point is None:
                    raise InvalidInputError(
                        f"{end} must be finite task coordinates, shape (m,); got "
                        f"{getattr(self, end)!r}"
                    )
                object.__setattr__(self, end, point)
            if np.shape(self.start) != np.shape(self.end):
                raise InvalidInputError("start and end differ in dimension")
            if self.shape is None:
                object.__setattr__(self, "shape", Line(self.start, self.end))
            ends = [self.shape.start, self.shape.end]
            if not np.allclose(ends, [self.start, self.end], rtol=0, atol=CLOSED):
                raise InvalidInputError("its path's ends are not its own")
            self._check_timing()

    def _check_timing(self) -> None:
        if self.profile not in PROFILES:
            raise InvalidInputError(f"profile {self.profile!r} is not one of {', '.join(PROFILES)}")
        if not (is_real(self.speed) and 0 < self.speed <= MAX_SPEED):
            raise InvalidInputError(
                f"speed must be > 0 and ≤ {MAX_SPEED:g} m/s; got {self.speed!r}"
            )
        acceleration = self.acceleration
        if self.profile == "trapezoidal" and not (
            is_real(acceleration) and 0 < acceleration <= MAX_ACCELERATION  # type: ignore[operator]
        ):
            given = "none given" if acceleration is None else f"got {acceleration!r}"
            raise InvalidInputError(
                f"a trapezoidal profile needs acceleration > 0 and ≤ {MAX_ACCELERATION:g} m/s² "
                f"(the tool's maximum); {given}"
            )
        if not self.duration <= MAX_DURATION:
            pace = f"speed {self.speed:g} m/s" + (
                f" and acceleration {self.acceleration:g} m/s²" if self.ramp else ""
            )
            raise InvalidInputError(
                f"at {pace} its path of {self.shape.length:.4g} m takes {self.duration:.3g} s; "
                f"a segment may take at most {MAX_DURATION:g} s: give a higher "
                + ("speed or acceleration" if self.ramp else "speed")
            )

    @cached_property
    def peak(self) -> float:
        """The highest speed reached, m/s: √(length · acceleration) where the path is too short
        to reach the ``speed``."""
        if self.profile == "constant":
            return self.speed
        return min(self.speed, math.sqrt(self.shape.length * self.acceleration))  # type: ignore[operator]

    @cached_property
    def ramp(self) -> float:
        """Duration of the acceleration (and of the deceleration), s; 0 at constant speed."""
        return 0.0 if self.profile == "constant" else self.peak / self.acceleration  # type: ignore[operator]

    @cached_property
    def duration(self) -> float:
        """t_f, in s: |Q − P| / speed for a line at constant speed."""
        return self.shape.length / self.peak + self.ramp

    @cached_property
    def breaks(self) -> np.ndarray:
        """The times in (0, duration), s, where ẏ_d is not smooth, (b,): where the trapezoidal
        profile's ramps end and begin (its acceleration jumps) and where a polyline turns at a
        corner (ẏ_d jumps); none on a line at constant speed. The adaptive integration ends a
        step at each (`redundancy.planning.integrate`)."""
        corners = getattr(self.shape, "cumulative", np.empty(0))[1:-1]
        ramps = [] if self.profile == "constant" else [self.ramp, self.duration - self.ramp]
        times = np.concatenate([self.time_at(corners), ramps])
        return distinct(times, self.duration)

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """The times (...,) in s at which the path has come the arc lengths s (...,), within
        [0, length]: `progress` inverted, s / v at constant speed; on the trapezoidal profile
        √(2 s / a) on the first ramp, s / v + t_a / 2 between, T − √(2 (L − s) / a) on the
        last."""
        s = np.asarray(s, dtype=float)
        if self.profile == "constant":
            return s / self.speed
        a, ramp, peak, length = (
            float(self.acceleration or 0.0),
            self.ramp,
            self.peak,
            self.shape.length,
        )
        cruise = s / peak + ramp / 2
        first = np.sqrt(2 * np.maximum(s, 0.0) / a)
        last = self.duration - np.sqrt(2 * np.maximum(length - s, 0.0) / a)
        return np.where(
            s < peak * ramp / 2, first, np.where(s > length - peak * ramp / 2, last, cruise)
        )

    def progress(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Arc length s and its rate ṡ at times t (...,) in s, both (...,); for the trapezoidal
        profile t is clipped to [0, duration] (at rest outside), and with a = acceleration,
        t_a = ramp, T = duration, v = peak: s = v (t − t_a/2) + a/2 (max(t_a − t, 0)² −
        max(t − T + t_a, 0)²), ṡ = min(v, a t, a (T − t))."""
        t = np.asarray(t, dtype=float)
        if self.profile == "constant":
            return self.speed * t, np.full(t.shape, self.speed)
        a, ramp, peak, end = float(self.acceleration or 0.0), self.ramp, self.peak, self.duration
        t = np.clip(t, 0.0, end)
        late = np.maximum(t - end + ramp, 0.0)
        s = peak * (t - ramp / 2) + a / 2 * (np.maximum(ramp - t, 0.0) ** 2 - late**2)
        return s, np.minimum(peak, a * np.minimum(t, end - t))

    @classmethod
    def along(
        cls,
        name: str,
        shape: Shape,
        speed: float,
        profile: str = "constant",
        acceleration: float | None = None,
        source: str = "",
    ) -> Segment:
        """The segment ``name`` along ``shape`` at ``speed`` m/s with the speed ``profile``
        (``source``: the task file's entry it was read from, which messages name)."""
        return cls(name, shape.start, shape.end, speed, shape, profile, acceleration, source)

    @property
    def steady(self) -> bool:
        """Whether ẏ_d is constant along the segment: a straight line at constant speed."""
        return self.shape.kind == "line" and self.profile == "constant"

    @cached_property
    def velocity(self) -> np.ndarray:
        """ẏ_d = (Q − P) / t_f (Eq. 34), constant, (m,) in m/s (read-only): a `steady` segment
        only (others: `velocity_at`)."""
        if not self.steady:
            raise InvalidInputError(
                f"segment {self.name}'s velocity varies along it; use velocity_at(t)"
            )
        velocity = (self.end - self.start) / self.duration
        velocity.setflags(write=False)
        return velocity

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """y_d(t) (..., m) for t (...,) in s (Eq. 33 on a line at constant speed)."""
        s, _ = self.progress(t)
        return self.shape.point(s)

    def velocity_at(self, t: np.ndarray | float) -> np.ndarray:
        """ẏ_d(t) (..., m) in m/s (and rad/s) for t (...,) in s."""
        s, rate = self.progress(t)
        return self.shape.tangent(s) * rate[..., None]

    def outline(self) -> np.ndarray:
        """Points (P, m) that draw the path as straight pieces."""
        return self.shape.outline()

    @property
    def label(self) -> str:
        """The path as messages name it."""
        return f"segment {self.name}"

    def describe(self) -> dict:
        """The segment's path and timing as JSON-ready data."""
        shape = self.shape
        found: dict = {"path": shape.kind, "length_m": shape.length, "duration_s": self.duration}
        if isinstance(shape, Arc):
            found.update(
                centre=shape.centre.tolist(),
                radius_m=shape.radius,
                sweep_deg=math.degrees(shape.sweep),
            )
        if isinstance(shape, Polyline) and shape.kind == "polyline":
            found["points"] = len(shape.points)
        found.update(profile=self.profile, speed=self.speed)
        if self.profile == "trapezoidal":
            found["acceleration"] = self.acceleration
        return found


@dataclass(frozen=True)
class Chain:
    """Segments travelled one after another as one path over time: ``position`` and
    ``velocity_at`` (right-continuous at the corners) of the whole, from t = 0."""

    name: str
    segments: tuple[Segment, ...]

    @property
    def start(self) -> np.ndarray:
        return self.segments[0].start

    @property
    def end(self) -> np.ndarray:
        return self.segments[-1].end

    @cached_property
    def offsets(self) -> np.ndarray:
        """The time each segment starts, (S + 1,) with the total duration last."""
        return np.concatenate([[0.0], np.cumsum([s.duration for s in self.segments])])

    @property
    def duration(self) -> float:
        """One pass through every segment, s."""
        return float(self.offsets[-1])

    @property
    def peak(self) -> float:
        """The highest speed any of its segments reaches, m/s."""
        return max(s.peak for s in self.segments)

    @cached_property
    def breaks(self) -> np.ndarray:
        """The times in (0, duration), s, where ẏ_d is not smooth, (b,): the corners between
        segments and each segment's own `Segment.breaks`."""
        inner = [s.breaks + offset for s, offset in zip(self.segments, self.offsets)]
        return distinct(np.concatenate([self.offsets[1:-1], *inner]), self.duration)

    def _each(self, t, method):
        t, piece = _piece(self.offsets, t)
        out = np.empty((*t.shape, len(self.start)))
        for i, segment in enumerate(self.segments):
            inside = piece == i
            if inside.any():
                out[inside] = getattr(segment, method)(t[inside] - self.offsets[i])
        return out

    def position(self, t):
        return self._each(t, "position")

    def velocity_at(self, t):
        return self._each(t, "velocity_at")

    def outline(self) -> np.ndarray:
        return np.concatenate([s.outline() for s in self.segments])

    @property
    def label(self) -> str:
        """The path as messages name it."""
        return f"cycle {self.name!r}"


def distinct(times: np.ndarray, duration: float) -> np.ndarray:
    """The sorted times (b,) among ``times`` inside (0, duration), each of them and the ends
    more than `SAME_TIME` × the duration apart: a break and its twin a rounding error away (a
    trapezoidal profile that never reaches its speed ends its ramp up where its ramp down begins)
    are one, as the integration's steps take them."""
    times = np.unique(times[(times > 0) & (times < duration)])
    edges = np.concatenate([[0.0], times])
    keep = (np.diff(edges) > SAME_TIME * duration) & (times < (1 - SAME_TIME) * duration)
    return times[keep]


def either_side(path: Segment | Chain) -> tuple[np.ndarray, np.ndarray]:
    """ẏ_d (b, m) just before and just after each of the path's `breaks` (b,): read `PROBE` × the
    time to its nearest neighbour (a break or an end) either side of it, so that no probe
    reaches past the next break, and at least a few rounding steps of the time, so that every
    probe reads another time than the break's."""
    breaks = path.breaks
    gaps = np.diff(np.concatenate([[0.0], breaks, [path.duration]]))
    probe = np.maximum(PROBE * np.minimum(gaps[:-1], gaps[1:]), 8 * np.spacing(breaks))
    before, after = (path.velocity_at(breaks + side * probe) for side in (-1.0, 1.0))
    return before, after


def jumps(path: Segment | Chain) -> np.ndarray:
    """The times (j,) s among the path's `breaks` where ẏ_d jumps (`jumped`, either side of
    each: `either_side`): a polyline's corner or a cycle's, turned at speed; not a speed
    profile's ramp end, where only its rate does, nor a corner where the path comes to rest and
    turns (ẏ_d is 0 either side). Found once and kept with the path (read-only), as its
    `breaks` are kept: a search scores every batch of motions by them."""
    kept = vars(path)  # a frozen path's derived values live there, as a cached_property's do
    if "jumps" not in kept:
        found = path.breaks[jumped(*either_side(path), path.peak)]
        found.flags.writeable = False
        kept["jumps"] = found
    return kept["jumps"]


def jumped(before: np.ndarray, after: np.ndarray, peak: float) -> np.ndarray:
    """Whether ẏ_d jumps from ``before`` to ``after`` (..., m), (...): it changes by more than
    `JUMP` of the path's ``peak`` speed, or of ẏ_d there where that is more (a tool's angle
    turning fast while its point moves slowly)."""
    speed = np.maximum(np.linalg.norm(before, axis=-1), np.linalg.norm(after, axis=-1))
    return np.linalg.norm(after - before, axis=-1) > JUMP * np.maximum(peak, speed)


def corners(path: Segment | Chain) -> np.ndarray:
    """The times (c,) s among the path's `breaks` where the direction of ẏ_d turns: its unit
    vectors u± either side (`either_side`) differ by more than `TURN` (|u₊ − u₋| = 2 sin(θ/2)
    for a turn by θ). A polyline's inner points and a cycle's corners between segments, where
    the path turns, at speed or where it stops; not a speed profile's ramp ends, nor a
    polyline's point on the line through its neighbours."""
    before, after = either_side(path)
    with np.errstate(invalid="ignore"):  # a ẏ_d of exactly 0 has no direction: not a turn
        units = [v / np.linalg.norm(v, axis=-1, keepdims=True) for v in (before, after)]
    return path.breaks[np.linalg.norm(units[1] - units[0], axis=-1) > TURN]


@dataclass(frozen=True)
class WorkCycle(Chain):
    """A task: its `Chain` of segments, the actuators a search holds, whether the last task
    coordinate is the tool's angle (rad), and the task file it was read from (for messages)."""

    held: tuple[str, ...] = ()
    tool_angle: bool = False
    source: str = field(default="", compare=False, repr=False)
    points: tuple[tuple[str, np.ndarray], ...] = field(default=(), compare=False, repr=False)

    def point_name(self, point: np.ndarray) -> str | None:
        """The name the task file gives ``point`` (m,) among its ``points``, or None."""
        return next((name for name, p in self.points if np.array_equal(p, point)), None)

    def __iter__(self) -> Iterator[Segment]:
        """The segments, in order (the cycle is indexed by their names)."""
        return iter(self.segments)

    def __getitem__(self, name: str) -> Segment:
        for segment in self.segments:
            if segment.name == name:
                return segment
        names = ", ".join(s.name for s in self.segments)
        raise InvalidInputError(f"no segment {name!r} in {self.name!r}; segments: {names}")

    @property
    def closed(self) -> bool:
        """Whether the last segment ends where the first starts."""
        return bool(np.all(np.abs(self.end - self.start) <= CLOSED))

    def chain(self) -> Chain:
        """The whole cycle as one path over time: the cycle itself."""
        return self

    def check_continuous(self, closed: bool = True) -> None:
        """`InvalidInputError` naming the first corner where a segment does not start where the
        one before ends (and, with ``closed``, where the cycle does not return to its start)."""
        pairs = list(zip(self.segments[:-1], self.segments[1:]))
        if closed:
            pairs.append((self.segments[-1], self.segments[0]))
        for before, after in pairs:
            if np.any(np.abs(after.start - before.end) > CLOSED):
                what = "it does not return to its start: " if after is self.segments[0] else ""
                raise InvalidInputError(
                    f"task {self.name!r} is not one continuous cycle; {what}segment "
                    f"{after.name} starts at {np.round(after.start, 6).tolist()} but "
                    f"{before.name} ends at {np.round(before.end, 6).tolist()}"
                )

    @property
    def angle_range(self) -> tuple[float, float]:
        """The least and the greatest tool angle the cycle's paths pass (rad, as written: a
        path moves its angle linearly between the values written at its points); (0, 0)
        without the angle."""
        if not self.tool_angle:
            return 0.0, 0.0
        angles = np.concatenate([s.outline()[:, -1] for s in self.segments])
        return float(angles.min()), float(angles.max())

    @property
    def angle_centre(self) -> float:
        """The middle of the tool angles the cycle passes (rad; 0 without the angle): the branch
        (c − π, c + π] that `redundancy.planning.angles` measures the angle on is centred
        there, so that it holds every one of them (their range is less than a turn)."""
        return sum(self.angle_range) / 2

    @classmethod
    def from_toml(cls, path: Path | str, dimension: int | None = None) -> WorkCycle:
        """Read a task file (schema in the module docstring); ``dimension`` (the robot's m, its
        position axes) checks every point's size, one more with ``tool_angle``."""
        path = Path(path)
        task = validate(TaskFile, read_toml(path, "task file"), str(path))
        size = None if dimension is None else dimension + int(task.tool_angle)
        found = _points(task, size, path)
        timing = {"speed": 0.5, **task.model_dump(include=set(TIMING), exclude_none=True)}
        if timing.get("profile") == "trapezoidal" and "acceleration" not in timing:
            raise InvalidInputError(
                f'{path}: profile = "trapezoidal" needs acceleration (m/s², the tool\'s maximum)'
            )
        segments = [
            _segment(entry, found, timing, task.tool_angle, size, path, f"{path}: segments[{i}]")
            for i, entry in enumerate(task.segments)
        ]
        if not segments:
            raise InvalidInputError(f"{path}: no segments")
        names = [segment.name for segment in segments]
        twice = next((name for name in names if names.count(name) > 1), None)
        if twice is not None:
            raise InvalidInputError(f"{path}: two segments are named {twice!r}; give one a name")
        if task.held == []:
            raise InvalidInputError(
                f"{path}: held = [] names no actuator (the actuators the improved search holds; "
                "leave it out for the default)"
            )
        name = path.stem if task.name is None else task.name
        held = tuple(task.held or ())
        segments = [replace(segment, held=held) for segment in segments]  # each knows its task's
        cycle = cls(name, tuple(segments), held, task.tool_angle, str(path), tuple(found.items()))
        lowest, highest = cycle.angle_range
        if highest - lowest >= 2 * np.pi:
            raise InvalidInputError(
                f"{path}: the tool's angle turns from {np.degrees(lowest):g}° to "
                f"{np.degrees(highest):g}°, a turn or more; the angle is measured within one "
                "turn: keep its values less than 360° apart"
            )
        return cycle


def _points(task: TaskFile, size: int | None, path: Path) -> dict[str, np.ndarray]:
    """A task file's named points, each of ``size`` coordinates where given (angles in rad);
    none are needed where every segment is a CSV polyline."""
    points = task.points
    if not points and all(isinstance(e, SegmentTable) and e.csv is not None for e in task.segments):
        return {}
    if not points:
        raise InvalidInputError(f"{path}: needs a [points] table of name = [coordinates]")
    found = {}
    for name, value in points.items():
        where = f"{path}: point {name}"
        if size is not None and len(value) != size:
            raise InvalidInputError(
                f"{where} has {len(value)} coordinates; the robot's task has {size}"
            )
        _check_reach(np.array(value), where, [repr(v) for v in value])
        found[name] = _in_radians(np.array(value), task.tool_angle)
    return found


def _check_reach(point: np.ndarray, where: str, shown: list[str]) -> None:
    """Refuse a point of a task file with a coordinate beyond `MAX_COORDINATE`, naming it as
    ``shown`` (one text per coordinate) at ``where``."""
    far = np.flatnonzero(np.abs(point) > MAX_COORDINATE)
    if far.size:
        raise InvalidInputError(
            f"{where}: {shown[far[0]]} lies beyond ±{MAX_COORDINATE:g} (m, or degrees for the "
            "tool's angle); a task point lies within that of the robot's base"
        )


def _in_radians(points: np.ndarray, tool_angle: bool) -> np.ndarray:
    """``points`` (..., m) with the last coordinate, where it is the tool's angle, in rad."""
    if not tool_angle:
        return points
    return np.concatenate([points[..., :-1], np.radians(points[..., -1:])], axis=-1)


def _segment(
    entry: SegmentTable | str,
    points: dict,
    timing: dict,
    tool_angle: bool,
    size: int | None,
    path: Path,
    where: str,
) -> Segment:
    """One entry of a task file's ``segments``: "<from>-<to>" or a table (module docstring),
    at the file's ``timing`` where it gives none of its own."""
    known = ", ".join(points)

    def point(name: str | None, key: str) -> np.ndarray:
        if name is None:
            raise InvalidInputError(f"missing {key!r} (a point's name)")
        if name not in points:
            raise InvalidInputError(
                f"{key} = {excerpt(name, toml)} must name a point among {known}"
            )
        return points[name]

    if isinstance(entry, str):
        ends = entry.split("-")
        if len(ends) != 2 or any(e not in points for e in ends):
            raise InvalidInputError(
                f"{path}: segment {excerpt(entry)} must be '<from>-<to>' with points among {known}"
            )
        entry = SegmentTable.model_validate({"from": ends[0], "to": ends[1], "name": entry})
    timing = {**timing, **entry.model_dump(include=set(TIMING), exclude_none=True)}
    if entry.csv is not None:
        given = entry.model_dump(by_alias=True, exclude_none=True)
        clash = [key for key in ARC_KEYS if key in given]
        if clash:
            raise InvalidInputError(f"{where}: a csv polyline takes no {', '.join(clash)}")
        dimension = size if size is not None or not points else len(next(iter(points.values())))
        with prefixed(where):
            shape: Shape = read_polyline(path.parent / entry.csv, dimension, tool_angle)
        name = Path(entry.csv).stem if entry.name is None else entry.name
    else:
        with prefixed(where):
            start, end = point(entry.start, "from"), point(entry.to, "to")
        name = f"{entry.start}-{entry.to}" if entry.name is None else entry.name
        with prefixed(f"{where} ({name})"):
            shape = _curve(entry, start, end, point, int(tool_angle))
    with prefixed(where):
        return Segment.along(name, shape, **timing, source=where)


def _curve(entry: SegmentTable, start, end, point, angles: int) -> Shape:
    """The line or arc from ``start`` to ``end`` a segment's table declares, its other points
    found by ``point(name, key)``."""
    centre = entry.centre if entry.centre is not None else entry.center
    if entry.via is not None and centre is not None:
        raise InvalidInputError("give via or centre, not both")
    if entry.via is not None:
        return Arc.through(start, point(entry.via, "via"), end, angles)
    if centre is None:
        if entry.direction is not None:
            raise InvalidInputError("direction belongs to an arc about a centre")
        return Line(start, end, angles)
    if entry.direction is None:
        raise InvalidInputError('an arc about a centre needs direction = "ccw" or "cw"')
    middle = point(centre, "centre")
    return Arc.about(start, end, middle[: len(middle) - angles], entry.direction, angles)


def read_polyline(path: Path | str, dimension: int | None, tool_angle: bool = False) -> Polyline:
    """The polyline of a CSV file (module docstring): one point per line, ``dimension`` values
    each where given (the last an angle in degrees with ``tool_angle``). Errors name the line."""
    path = Path(path)
    rows: list[tuple[int, np.ndarray]] = []
    for number, point in _csv_points(path):
        size = dimension or len(rows[0][1] if rows else point)
        if len(point) != size:
            why = (
                f"the task has {dimension} coordinates per point"
                if dimension
                else f"line {rows[0][0]} has {size}"
            )
            raise InvalidInputError(f"{path} line {number}: {len(point)} values; {why}")
        rows.append((number, point))
    if not rows:
        raise InvalidInputError(f"{path}: no points; a polyline needs at least two")
    angles = int(tool_angle)
    kept = [rows[0][1]]
    for _, point in rows[1:]:
        if np.linalg.norm(_position(point - kept[-1], angles)) > CLOSED:
            kept.append(point)
    if len(kept) < 2:
        first = rows[0][0]
        where = f"line {first}" if len(rows) == 1 else f"lines {first}-{rows[-1][0]}"
        raise InvalidInputError(
            f"{path}: one point ({where}); a polyline needs at least two distinct points"
        )
    return Polyline(_in_radians(np.array(kept), tool_angle), angles)


def _csv_points(path: Path):
    """(line number, point) of each line of a CSV file that holds one: blank lines, comments
    ("#") and a first line of names (no cell a number, ``inf`` and ``nan`` being numbers) are
    skipped."""
    lines = read_text(path, "CSV file").splitlines()
    header = True  # the first line that holds anything may be one of names
    for number, cells in enumerate(csv.reader(lines), start=1):
        if not "".join(cells).strip() or lines[number - 1].lstrip().startswith("#"):
            continue
        values = [_cell(cell) for cell in cells]
        names, header = header and all(v is None for v in values), False
        if names:
            continue
        where = f"{path} line {number}"
        bad = [i for i, v in enumerate(values) if v is None or not math.isfinite(v)]
        if bad:
            text = excerpt(cells[bad[0]].strip())
            raise InvalidInputError(f"{where}: cell {bad[0] + 1} ({text}) is not a finite number")
        _check_reach(np.array(values), where, [c.strip() for c in cells])
        yield number, np.array(values)


def _cell(text: str) -> float | None:
    """The number a CSV cell writes, finite or not, or None where it writes none."""
    try:
        return decimal(text)
    except ValueError:
        return None


def checked_path(path: object, name: str = "segment") -> Segment | Chain:
    """``path`` if it is one the integrators take (a `Segment`, or a `Chain` such as a
    `WorkCycle`), else one line naming what was given: a segment's name is looked up in its
    `WorkCycle`."""
    if isinstance(path, Segment | Chain):
        return path
    raise InvalidInputError(
        f"{name} must be a Segment or a Chain (e.g. cycle[{path!r}] of a WorkCycle, or the "
        f"WorkCycle itself); got {type(path).__name__} {path!r}"[:240]
    )
