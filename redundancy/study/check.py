"""A new machine checked before it is studied: one screen saying what would stop a study.

For each actuator, its joint is swept over the joint's range (the other joints at mid-range):
- the actuator's values over that sweep against its declared stroke: a stroke no value reaches
  blocks a study; a stroke end beyond the values reached is a mismatch to fix in the
  declaration;
- where det A changes sign or vanishes along the sweep, A = ∂x/∂q (Eq. 11) is singular: for a
  cylinder on a revolute joint, its line passes through the joint axis (the torque arm of
  Eq. 14 vanishes). Inside the stroke this blocks a study: J_H = J A⁻¹ is undefined there.

And for the machine: masses (a kinematic-only robot studies the velocity objective only),
meshes (links whose meshes are missing are drawn as hulls), and whether each task point is
reached inside the joint ranges with every stroke kept, for some value of the held actuators.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass

import numpy as np

from redundancy.errors import (
    InvalidInputError,
    SingularConfigurationError,
    UnreachableError,
    placed,
)
from redundancy.model.linkage import LinkageCylinder
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.angles import task_labels
from redundancy.planning.ik import check_path, free_configurations, inverse_kinematics
from redundancy.planning.starts import held_actuators, stroke_box
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.limits import Limits, amount
from redundancy.resolution.state import evaluate

SWEEP = 1441  # joint values per sweep: a quarter degree over a full turn
REACH_SAMPLES = 20_000  # configurations sampled for the reachable area (the workspace figure)
HELD_SAMPLES = 9  # held values tried for each task point, with one held actuator
HELD_BUDGET = 81  # held value combinations tried for each task point, with several
FREE_SEEDS = 64  # seeds of the free inverse kinematics where no held value reaches a point
MISMATCH = 1e-3  # m or rad: a stroke end this far beyond the values reached is a mismatch
HELD_PROBES = 16  # configurations over the joint ranges where the held actuators' others are
# asked to move the tool along every task axis
NO_LIMIT = 1e3  # m or rad: a joint range wider is a URDF's "no limit" (±1e16), swept a turn


@dataclass(frozen=True)
class ActuatorCheck:
    """One actuator over its joint's range: the ``reached`` values [min, max] of x_i against
    its ``stroke``, the joint values (its joint's unit) where A is ``singular``, with x_i
    there (``singular_x``), and the joint values [min, max] where x_i is ``undefined`` (a
    linkage that cannot close), or None. ``linkage``: it drives its joint through a four-bar
    linkage."""

    name: str
    joint: str
    rotary: bool
    joint_rotary: bool
    linkage: bool
    stroke: tuple[float, float]
    reached: tuple[float, float]
    singular: tuple[float, ...]
    singular_x: tuple[float, ...]
    undefined: tuple[float, float] | None

    @property
    def why_undefined(self) -> str:
        """Why x_i has no value over part of its joint's range."""
        return "its linkage cannot close" if self.linkage else "its geometry gives it no value"

    @property
    def undefined_range(self) -> str:
        """Where x_i has no value, in words: "for joint within [low, high]"."""
        low, high = (self.joint_value(v) for v in self.undefined or ())
        return f"for {self.joint} within [{low}, {high}]"

    @property
    def why_singular(self) -> str:
        """Why A is singular where it is: the actuator cannot move its joint there."""
        if self.linkage:
            return "a line of its linkage passes through a pivot (a dead centre)"
        return "its line passes through the joint axis"

    @property
    def unreachable(self) -> bool:
        """No value of the stroke is reached over the joint's range."""
        return self.reached[1] < self.stroke[0] or self.reached[0] > self.stroke[1]

    @property
    def mismatch(self) -> bool:
        """A finite stroke end lies beyond the values reached (by more than `MISMATCH`)."""
        lower, upper = self.stroke
        return bool(
            (np.isfinite(lower) and lower < self.reached[0] - MISMATCH)
            or (np.isfinite(upper) and upper > self.reached[1] + MISMATCH)
        )

    def joint_value(self, value: float) -> str:
        """A value of the actuator's joint, in mm or degrees."""
        return amount(value, "rad" if self.joint_rotary else "m")

    def singular_lines(self) -> list[str]:
        """One line per singular configuration inside the stroke, naming the joint value and
        the actuator's value there, and one where the actuator is not defined over part of its
        joint's range."""
        unit = "rad" if self.rotary else "m"
        found = [
            f"{self.name}: A is singular at {self.joint} = {self.joint_value(joint)} "
            f"({self.name} = {amount(x, unit)}, inside its stroke)"
            for joint, x in zip(self.singular, self.singular_x)
            if self.stroke[0] <= x <= self.stroke[1]
        ]
        if self.undefined is not None:
            found.append(
                f"{self.name}: {self.why_undefined} {self.undefined_range}, inside the joint's "
                f"range: keep {self.joint}'s limits where it has one"
            )
        return found


@dataclass(frozen=True)
class Check:
    """The checks of one robot and, where a task is given, of its points: ``points`` (P, m),
    in the order the segments meet them, their ``names`` in the task file (None for a CSV
    polyline's end) and whether each is ``reached`` with every stroke kept."""

    robot: Robot
    actuators: tuple[ActuatorCheck, ...]
    points: np.ndarray | None
    reached: tuple[bool, ...]
    held: tuple[str, ...] = ()  # why the task's held actuators cannot be held (`held_problems`)
    paths: tuple[str, ...] = ()  # the segments a study refuses between their ends (`_paths`)
    names: tuple[str | None, ...] = ()

    def point(self, i: int) -> str:
        """Point ``i`` as the check names it: its name in the task file, then where it is."""
        name = self.names[i] if i < len(self.names) else None
        where = task_point(self.robot, np.asarray(self.points)[i])
        return where if name is None else f"{name} at {where}"

    def blocking(self) -> list[str]:
        """What stops a study, one line each (empty when the robot is ready)."""
        robot = self.robot
        found = []
        if robot.n <= robot.m:
            found.append(
                f"n = {robot.n} joints for a task of m = {robot.m} (tool {robot.task_axes}): no "
                "redundancy to resolve"
            )
        for a in self.actuators:
            if a.unreachable:
                found.append(f"{a.name}: no value of its stroke is reached over {a.joint}'s range")
            found += a.singular_lines()
        found += self.held
        if self.points is not None:
            found += [
                f"task point {self.point(i)} is not reached inside the joint ranges and strokes"
                for i, ok in enumerate(self.reached)
                if not ok
            ]
        return found + list(self.paths)


def held_problems(robot: Robot, cycle: WorkCycle, sampled: bool = True) -> list[str]:
    """Why ``cycle``'s held actuators cannot be held, one line each naming the file and table
    that fix it: the task must hold as many actuators as the robot has redundant degrees, n − m
    (a machine whose undeclared joints move freely, a chassis say, has too many: lock them), and
    each held actuator needs a finite stroke where its values are ``sampled`` (a search, the
    default start)."""
    source = robot.actuators.source
    if not source.endswith(".toml"):
        source = f"a robot.toml beside {source or 'the URDF'}"
    try:
        held = held_actuators(robot, cycle)
    except InvalidInputError as error:  # no redundancy
        return [str(error)]
    try:
        robot.actuators.rows(held)
    except InvalidInputError as error:  # the task file holds actuators the robot does not have
        return [placed(cycle.source and f"{cycle.source}: held", str(error))]
    redundant = robot.n - robot.m
    if len(held) != redundant:
        line = (
            f"task {cycle.name!r} holds {list(held)}, but {robot.name} has n − m = "
            f"{robot.n} − {robot.m} = {redundant} redundant degrees: hold that many actuators"
        )
        free = [a.joint for a in robot.actuators if not a.declared_in]
        if redundant > len(held) and free:
            line += (
                f", or lock the joints the task does not move with locked_joints in {source} "
                f"(joints without an actuator declaration: {', '.join(free)})"
            )
        return [placed(cycle.source and f"{cycle.source}: held", line)]
    problems = []
    for name in held if sampled else ():
        actuator = robot.actuators[name]
        if np.isfinite(actuator.lower) and np.isfinite(actuator.upper):
            continue
        place = actuator.declared_in or (
            f'{source}: [actuators.{name}] (a table to add, with kind = "Identity" and joint '
            f"= {actuator.joint!r})"
        )
        syntax = (
            '<stroke lower=".." upper=".."/>'
            if "<transmission" in place
            else "stroke = [lower, upper]"
        )
        problems.append(
            f"held actuator {name} has no finite stroke to sample, "
            f"{span(actuator.lower, actuator.upper, actuator.unit)}: give it one in {place}: "
            f"{syntax} ({actuator.unit})"
        )
    most, all_free = held_motions(robot, held)
    if most < all_free == robot.m:  # a task axis no actuator moves along is said at the path
        names = robot.actuators.names
        others = [name for name in names if name not in held]
        line = (
            f"holding {', '.join(held)} leaves {', '.join(others)} at most {most} of the task's "
            f"{robot.m} directions to move the tool in, anywhere in the joint ranges: they reach "
            "a task point at isolated held values at most, which no search can sample; hold "
            "other actuators"
        )
        working = (  # the latest actuators that work, as the default takes the last ones
            list(chosen)
            for chosen in itertools.combinations(reversed(names), len(held))
            if held_motions(robot, chosen)[0] == robot.m
        )
        example = next(working, None)
        if example is not None:
            line += f", e.g. held = {json.dumps(example[::-1], ensure_ascii=False)}"
        problems.append(placed(cycle.source and f"{cycle.source}: held", line))
    return problems


def held_motions(robot: Robot, held: tuple[str, ...]) -> tuple[int, int]:
    """In how many task directions, at most, the other actuators move the tool while ``held``
    keep their strokes: the rank of J N, N a basis of the motions A_h q̇ = 0 (the null space of
    the held rows of A), the most over `HELD_PROBES` configurations over the joint ranges; and
    in how many every actuator does, the rank of J. A slew held on a crane whose task is 3-D
    leaves the boom's cylinders the vertical plane: 2 of 3; the Panda's four last joints held
    leave its shoulder, whose three axes meet in one point, a sphere about it: 2 of 3. Probes
    where A or J is not finite are left out; where none is left, (m, m)."""
    rows = robot.actuators.rows(list(held))
    lower, upper = robot.span
    q = lower + (upper - lower) * np.random.default_rng(0).random((HELD_PROBES, robot.n))
    space = evaluate(robot, q)
    finite = np.isfinite(space.A).all(axis=(1, 2)) & np.isfinite(space.J).all(axis=(1, 2))
    if not finite.any():  # nowhere to tell (a linkage past its dead centres): not refused
        return robot.m, robot.m

    def rank(matrix: np.ndarray) -> int:
        singular = np.linalg.svd(matrix, compute_uv=False)
        return int(np.sum(singular > 1e-9 * max(singular[0], 1e-300)))

    most = free = 0
    for A, J in zip(space.A[finite], space.J[finite]):
        N = np.linalg.svd(A[rows])[2][len(rows) :].T  # the motions that keep the held strokes
        most, free = max(most, rank(J @ N)), max(free, rank(J))
    return most, free


def task_point(robot: Robot, point: np.ndarray) -> str:
    """A task point (m,) as messages show it: positions in mm, the tool's angle in degrees."""
    units = ["rad" if label == "angle" else "m" for label in task_labels(robot)]
    return f"[{', '.join(amount(v, unit) for v, unit in zip(point, units))}]"


def span(lower: float, upper: float, unit: str) -> str:
    """A range [lower, upper] in the SI ``unit`` ("m" or "rad") as messages show it (mm,
    degrees); an infinite end as ∞."""
    ends = [amount(v, unit) if np.isfinite(v) else ("-∞" if v < 0 else "∞") for v in (lower, upper)]
    return f"[{ends[0]}, {ends[1]}]"


def _sweep(robot: Robot, column: int, row: int) -> tuple:
    """Actuator ``row`` over joint ``column``'s range: its values' [min, max] where defined,
    the joint values where det A vanishes or changes sign, with the actuator's value there, and
    the joint values [min, max] where the actuator is not defined (None where it is
    everywhere). A range is swept as declared, wider than a turn too (a slew of ±200°), unless
    it is unbounded or a URDF's "no limit" (`NO_LIMIT`): then over the turn of `Robot.span`."""
    declared = robot.upper - robot.lower <= NO_LIMIT  # False where unbounded
    turn_lower, turn_upper = robot.span
    lower = np.where(declared, robot.lower, turn_lower)
    upper = np.where(declared, robot.upper, turn_upper)
    q = np.repeat(((lower + upper) / 2)[None], SWEEP, axis=0)
    q[:, column] = np.linspace(lower[column], upper[column], SWEEP)
    space = evaluate(robot, q)
    x = space.x[:, row]
    defined = np.isfinite(x) & np.isfinite(space.A[:, row]).all(axis=1)
    whole = np.isfinite(space.A).all(axis=(1, 2))
    det = np.full(SWEEP, np.nan)  # no sign, so no singular configuration, where undefined
    det[whole] = np.linalg.det(space.A[whole])
    i = np.flatnonzero((np.sign(det[:-1]) * np.sign(det[1:]) < 0) | (det[:-1] == 0))
    step = det[i] - det[i + 1]  # nonzero where the sign changes
    weight = np.divide(det[i], step, out=np.zeros_like(step), where=det[i] != 0)
    singular = q[i, column] + weight * (q[i + 1, column] - q[i, column])
    singular_x = x[i] + weight * (x[i + 1] - x[i])
    reached = (
        (float(x[defined].min()), float(x[defined].max())) if defined.any() else (np.inf, -np.inf)
    )
    outside = q[~defined, column]
    undefined = (float(outside.min()), float(outside.max())) if outside.size else None
    return reached, tuple(singular.tolist()), tuple(singular_x.tolist()), undefined


def _reached(robot: Robot, cycle: WorkCycle) -> tuple[np.ndarray, tuple[bool, ...]]:
    """The task's points (P, m) and whether each is reached inside the joint ranges with every
    stroke kept, for one of a grid of held values over their strokes: `HELD_SAMPLES` values
    with one held actuator, at most `HELD_BUDGET` combinations with several; where none does,
    by a configuration the actuators reach free (`FREE_SEEDS` seeds), which that grid, coarse
    over several held actuators, may have passed between."""
    held = held_actuators(robot, cycle)
    count = min(HELD_SAMPLES, max(2, int(HELD_BUDGET ** (1 / len(held)) + 1e-9)))
    grids = [np.linspace(lower, upper, count) for lower, upper in stroke_box(robot, held)]
    values = np.array(list(itertools.product(*grids)))
    strokes = Limits.strokes(robot)
    met = [p for s in cycle.segments for p in (s.start, s.end)]
    points = np.array(
        [p for i, p in enumerate(met) if not any(np.array_equal(p, o) for o in met[:i])]
    )
    reached = []
    for point in points:
        found = inverse_kinematics(robot, point, held, values)
        kept = strokes.margin(evaluate(robot, found.q).x) >= 0
        ok = bool(np.any(found.reached & kept))
        if not ok:  # a grid of several held actuators' values may pass between the solutions
            free, _ = free_configurations(robot, point, FREE_SEEDS)
            ok = len(free) > 0 and bool(np.any(strokes.margin(evaluate(robot, free).x) >= 0))
        reached.append(ok)
    return points, tuple(reached)


def check(robot: Robot, cycle: WorkCycle | None = None) -> Check:
    """Check ``robot`` (and the points of ``cycle``, where given) for a study."""
    require_robot(robot)
    actuators = tuple(
        ActuatorCheck(
            a.name,
            a.joint,
            bool(a.rotary),
            bool(robot.rotary_joints[a.index]),
            isinstance(a, LinkageCylinder),
            (a.lower, a.upper),
            *_sweep(robot, a.index, row),
        )
        for row, a in enumerate(robot.actuators)
    )
    points: np.ndarray | None = None
    reached_points: tuple[bool, ...] = ()
    held: list[str] = []
    paths: tuple[str, ...] = ()
    names: tuple[str | None, ...] = ()
    if cycle is not None and robot.n > robot.m:  # with no redundancy, the one blocking line
        held = held_problems(robot, cycle)
        if not held and not any(a.undefined for a in actuators):  # its points next, if it can
            points, reached_points = _reached(robot, cycle)
            names = tuple(cycle.point_name(p) for p in points)
            paths = _paths(robot, cycle, points[~np.array(reached_points)])
    return Check(robot, actuators, points, reached_points, tuple(held), paths, names)


def _paths(robot: Robot, cycle: WorkCycle, missed: np.ndarray) -> tuple[str, ...]:
    """Why a study refuses a segment between its ends, as the study says it (`check_path`):
    a point of an arc or a recorded path out of reach, or a start where the tool cannot move
    along some task direction; segments ending at a ``missed`` point are named by that."""
    found = []
    for segment in cycle.segments:
        if any(np.array_equal(segment.start, p) or np.array_equal(segment.end, p) for p in missed):
            continue
        try:
            check_path(robot, segment)
        except (UnreachableError, SingularConfigurationError) as error:
            found.append(str(error))
    return tuple(found)


def reachable_points(robot: Robot, checked: tuple[str, ...], seed: int = 0) -> np.ndarray:
    """Task points y (k, m) the machine reaches with every ``checked`` stroke kept: y(q) at
    `REACH_SAMPLES` configurations drawn uniformly over the joint ranges (an unbounded joint
    over one turn, [−π, π]), those that leave a checked stroke dropped. A sample of the
    reachable area, seeded so that a study draws the same one every time."""
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    q = np.random.default_rng(seed).uniform(lower, upper, (REACH_SAMPLES, robot.n))
    space = evaluate(robot, q)
    kept = Limits.strokes(robot, checked).margin(space.x) >= 0
    return space.y[kept]
