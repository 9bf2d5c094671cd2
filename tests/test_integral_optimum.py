"""The global optimum of integral objectives by dynamic programming over the held actuators:
the planar 4R arm of Kazerounian & Wang on its closed circle, with and without the obstacle
term, beside the local pseudoinverse and the improved start; two held actuators (r = 2).

The setting is the one the public ROS implementation of Ferrentino et al. (Robotics 10(1) 42,
2021; github.com/unisa-acg/moveit_dp_redundancy_resolution, its fourr_kazerounian packages)
gives for the 4R arm (tests/data/kw4r): links 7, 7, 4, 1.5 m; the circle of radius 4 m about
(6, 4) m from (10, 4) m, counterclockwise, the tool's angle at −60° (m = 3, r = 1, the first
joint held, as there); joint speeds within 2 rad/s and accelerations within 10 rad/s²; the
objective 0.1 ∫ q̇ᵀq̇ dt + 0.9 ∫ |p₃ − o|² dt, p₃ the third joint's position and o = (6, 4) m
the "obstacle" point of that objective (its distance squared, minimised, as the implementation
defines it). Chosen here, not taken from either source: the timing (a trapezoidal profile of
3.5 m/s and 2 m/s², 8.93 s, near the implementation's 9 s rest-to-rest), the link masses, and
the joint ranges (±π instead of continuous joints). Kazerounian & Wang's paper itself was not
read.
"""

import itertools
from pathlib import Path

import numpy as np
import pytest
from slewing3r_closed_form import start_configuration

from redundancy import load_robot
from redundancy.errors import InvalidInputError
from redundancy.planning.angles import task_robot
from redundancy.planning.ik import inverse_kinematics
from redundancy.planning.integral_optimum import (
    IntegralOptimum,
    OptimumGrid,
    _measure_stage,
    _optimum,
    _pass,
    _result,
    integral_optimum,
)
from redundancy.planning.refinement import CONVERGED
from redundancy.planning.starts import improved_start
from redundancy.planning.tasks import Arc, Segment, WorkCycle
from redundancy.resolution.laws import MinVelocityNorm
from redundancy.resolution.limits import TOLERANCE, Limits
from redundancy.resolution.objectives import Objective, velocity_norm
from redundancy.resolution.state import ActuatorSpace, evaluate
from redundancy.study.integral import compare

ARM = Path(__file__).parent / "data" / "kw4r"
SLEWING = Path(__file__).parent / "data" / "slewing3r"
SPEED, ACCELERATION = 2.0, 10.0  # rad/s, rad/s², every joint
OBSTACLE = np.array([6.0, 4.0])  # m

SQUARED = Objective("joint_speeds", MinVelocityNorm(), velocity_norm, "q̇ᵀq̇", "rad²/s²", "integral")


def obstacle_term(space: ActuatorSpace, x_dot: np.ndarray) -> np.ndarray:
    """0.1 q̇ᵀq̇ + 0.9 |p₃ − o|² (k,): x = q for these joints, and p₃, the third joint's
    position, in closed form from the first two joints (links of 7 m)."""
    q1, q12 = space.q[:, 0], space.q[:, 0] + space.q[:, 1]
    p3 = 7 * np.column_stack([np.cos(q1) + np.cos(q12), np.sin(q1) + np.sin(q12)])
    return 0.1 * velocity_norm(space, x_dot) + 0.9 * np.sum((p3 - OBSTACLE) ** 2, axis=1)


WITH_OBSTACLE = Objective(
    "joint_speeds_and_obstacle", MinVelocityNorm(), obstacle_term, "cost", "1", "integral"
)


@pytest.fixture(scope="module")
def arm():
    base = load_robot(ARM / "robot.toml")
    cycle = WorkCycle.from_toml(ARM / "task.toml", dimension=base.m)
    return base, task_robot(base, cycle), cycle["circle"]


def _compare(arm, objective, grids=(50, 100)):
    _, robot, circle = arm
    return compare(robot, circle, objective, "x1", SPEED, ACCELERATION, grids=grids)


@pytest.fixture(scope="module")
def plain(arm):
    """∫ q̇ᵀq̇ dt three ways."""
    return _compare(arm, SQUARED)


@pytest.fixture(scope="module")
def steered(arm):
    """The same with the obstacle term, where the acceleration limit binds: the optimum's
    motion rides it, and its grid of held values must be finer than h² ẍ_max."""
    return _compare(arm, WITH_OBSTACLE, (50, 100, 200, 400))


def on_nodes(robot, objective: Objective, search, t: np.ndarray) -> float:
    """The improved start's motion sampled at the nodes t (N + 1,) scored by the recursion's
    own stage cost: the same discretisation as the optimum's."""
    q = search.motion(time_step=t[1]).q[0]
    assert q.shape[0] == len(t)
    space = evaluate(robot, q)
    stage = _measure_stage(objective, space, space.x[:, None])
    return sum(float(stage(j, t[1], np.ones((1, 1), bool))[0, 0]) for j in range(len(t) - 1))


def test_the_optimum_is_never_above_the_improved_start(arm, plain, steered):
    """On the 4R circle, with and without the obstacle term, the optimum over the held first
    joint's histories lies at or below the improved start's motion sampled at the same nodes
    and scored by the same stage cost; the improved start lies at or below the local
    pseudoinverse from the default start; and the optimum keeps the joints' speed and
    acceleration limits, from rest and to rest as the circle's timing starts and ends."""
    _, robot, _ = arm
    for comparison in (plain, steered):
        local, improved, optimum = comparison.figures
        found = comparison.optimum
        assert found.optimum <= on_nodes(robot, comparison.objective, comparison.search, found.t)
        assert improved.integral <= local.integral
        assert optimum.speed <= SPEED + 1e-9 and optimum.acceleration <= ACCELERATION + 1e-9
        ends = np.abs(found.x[[1, -2]] - found.x[[0, -1]]) / found.t[1] ** 2
        assert ends.max() <= ACCELERATION + 1e-9


def test_the_optimum_converges_under_refinement_and_says_where_acceleration_binds(plain, steered):
    """Refining the time grid from 50 to 100 intervals moves the optimum of ∫ q̇ᵀq̇ dt by less
    than 0.5 %. With the obstacle term the joints' speed and acceleration limits bind, and the
    optimum is still the global one over its grid (the recursion checks the acceleration on
    every path); from 200 to 400 intervals it moves by less than 0.5 %. Each is converged
    exactly where its last change is below the rule's threshold."""
    assert [g.intervals for g in plain.optimum.grids] == [50, 100]
    assert [g.intervals for g in steered.optimum.grids] == [50, 100, 200, 400]
    for comparison in (plain, steered):
        assert comparison.optimum.converged and comparison.optimum.change < 0.005
        assert comparison.optimum.converged == (comparison.optimum.change < CONVERGED)
        assert comparison.figures[2].strategy == "global optimum"
    assert not plain.optimum.acceleration_binds and steered.optimum.acceleration_binds
    optimum = steered.figures[2]
    assert optimum.speed == pytest.approx(SPEED, rel=1e-4)
    assert optimum.acceleration == pytest.approx(ACCELERATION, rel=1e-4)


def _exhaustive(x, costs, t, speeds, accelerations, rest):
    """The least cost over every path through the nodes' values x (N + 1, G, n) keeping the
    speed and acceleration limits (the latter from and to rest where ``rest``), with the
    transition costs ``costs`` (N, G, G), summed in the recursion's order."""
    h, best = t[1], np.inf
    for path in itertools.product(range(x.shape[1]), repeat=len(t)):
        x_dot = np.diff(x[np.arange(len(t)), path], axis=0) / h
        still = [np.zeros((int(at_rest), x.shape[2])) for at_rest in rest]
        moving = np.concatenate([still[0], x_dot, still[1]])
        if np.any(np.abs(x_dot) > speeds) or np.any(
            np.abs(np.diff(moving, axis=0)) > h * accelerations
        ):
            continue
        cost = 0.0
        for j in range(len(t) - 1):
            cost += costs[j, path[j], path[j + 1]]
        best = min(best, cost)
    return best


def _table(costs):
    """The stage cost of transition costs (N, G, G) given in a table."""
    return lambda j, h, allowed: np.where(allowed, costs[j], np.inf)


def test_the_recursion_is_exhaustive_without_accelerations_and_keeps_them_with():
    """On small random problems (N = 4 intervals, G = 4 values, two actuators), the recursion's
    least cost is exactly the least over every path, where speeds alone are limited and where
    accelerations are too (from and to rest); its path keeps the limits and costs what the path
    costs, and its cost without the acceleration limit is the speeds-only optimum."""
    rng = np.random.default_rng(7)
    t, speeds, free = np.linspace(0.0, 1.0, 5), np.full(2, 3.0), np.full(2, np.inf)
    bound = 0
    for _ in range(40):
        x = rng.uniform(0.0, 1.0, (5, 4, 2))
        costs = rng.uniform(0.0, 1.0, (4, 4, 4))
        usable, stage = np.ones((5, 4), bool), _table(costs)
        cost, _, unlimited = _pass(x, usable, stage, t, speeds, free)
        assert cost == unlimited == _exhaustive(x, costs, t, speeds, free, (False, False))
        accelerations, rest = np.full(2, 12.0), (True, True)
        cost, path, unlimited = _pass(x, usable, stage, t, speeds, accelerations, rest)
        assert unlimited == _exhaustive(x, costs, t, speeds, free, rest)
        assert cost == _exhaustive(x, costs, t, speeds, accelerations, rest)
        if np.isfinite(cost):
            moves = np.diff(x[np.arange(5), path], axis=0) / t[1]
            assert np.abs(moves).max() <= 3.0 + 1e-9
            changes = np.diff(np.concatenate([[[0, 0]], moves, [[0, 0]]]), axis=0)
            assert np.abs(changes).max() <= t[1] * 12.0 + 1e-9
            assert cost == sum(costs[j, path[j], path[j + 1]] for j in range(4))
            bound += cost > unlimited
    assert bound  # the acceleration limit binds on some of them


def test_the_optimum_rides_a_joint_limit_between_the_tables_solved_values():
    """The crane's 3-1, ∫ ẋᵀẋ dt on 20 intervals: the least cost keeps the lift cylinder at the
    end of its stroke, where its joint reaches its limit, between two of the 81 telescope values
    solved exactly. Those tables left out the cell across the limit, so no path reached it: the
    optimum was 0.47 % above an exhaustive recursion over 1,200 telescope values solved exactly
    at every node. With the joint ranges checked where the tables interpolate, it is within
    0.05 % of it (the recursions' grids differ)."""
    crane = load_robot("hiab031")
    segment = WorkCycle.from_toml(crane.task_file, dimension=crane.m)["3-1"]
    velocity = Objective("squared", MinVelocityNorm(), velocity_norm, "ẋᵀẋ", "m²/s²", "integral")
    found = integral_optimum(crane, segment, velocity, "x3", grids=(20,))
    t = np.linspace(0.0, segment.duration, 21)
    values = np.linspace(crane.actuators.lower[2], crane.actuators.upper[2], 1200)
    strokes, joints = Limits.strokes(crane), Limits.joints(crane)
    x, inside = [], []
    for point in segment.position(t):
        solved = inverse_kinematics(crane, point, ["x3"], values[:, None], seeds=2)
        space = evaluate(crane, solved.q)
        x.append(space.x)
        inside.append(
            solved.reached
            & (strokes.margin(space.x) >= -TOLERANCE)
            & (joints.margin(solved.q) >= -TOLERANCE)
        )
    h, cost = t[1], np.where(inside[0], 0.0, np.inf)
    for j in range(20):  # the stage cost h (c_j + c_j+1) / 2 with the chord's ẋ: |Δx|² / h
        step = x[j + 1][None] - x[j][:, None]
        stage = np.where(inside[j + 1][None], np.sum(step**2, axis=2) / h, np.inf)
        cost = np.min(cost[:, None] + stage, axis=0)
    assert found.optimum == pytest.approx(cost.min(), rel=5e-4)


def test_a_user_defined_obstacle_term_steers_the_optimum(plain, steered):
    """The obstacle term, a measure written here, runs through the same dynamic programming:
    its optimum keeps the third joint nearer the point o than the plain optimum does, at the
    price of larger joint speeds, and its integral is the measure's along its own path."""

    def distance(found):
        q1, q12 = found.q[:, 0], found.q[:, 0] + found.q[:, 1]
        p3 = 7 * np.column_stack([np.cos(q1) + np.cos(q12), np.sin(q1) + np.sin(q12)])
        return np.linalg.norm(p3 - OBSTACLE, axis=1).mean()

    def squared_speeds(found):
        return np.sum(np.diff(found.x, axis=0) ** 2) / found.t[1]

    assert distance(steered.optimum) < distance(plain.optimum)
    assert squared_speeds(steered.optimum) > squared_speeds(plain.optimum)
    assert squared_speeds(plain.optimum) == pytest.approx(plain.optimum.optimum, rel=1e-12)


def test_two_held_actuators_get_a_global_optimum(arm):
    """r = 2: the arm without the tool's angle (m = 2) holding its last two joints. The optimum
    of ∫ q̇ᵀq̇ dt over both joints' histories keeps their strokes and the speed limit, and lies
    below the improved start (a sweep of both joints' starts) within its last refinement."""
    base, _, _ = arm
    circle = Segment.along(
        "circle", Arc.about([10.0, 4.0], [10.0, 4.0], [6.0, 4.0], "ccw"), 3.5, "trapezoidal", 2.0
    )
    held = ("x3", "x4")
    found = integral_optimum(base, circle, SQUARED, held, grids=(20, 40), speeds=SPEED)
    assert found.held == held and found.r.shape == (41, 2) and found.x.shape == (41, 4)
    rows = base.actuators.rows(held)
    assert np.abs(found.r - found.x[:, rows]).max() < 1e-9
    strokes = base.actuators
    assert np.all((found.x >= strokes.lower - 1e-9) & (found.x <= strokes.upper + 1e-9))
    assert np.abs(np.diff(found.x, axis=0)).max() / found.t[1] <= SPEED + 1e-9
    search = improved_start(base, circle, SQUARED, held)
    assert found.optimum <= on_nodes(base, SQUARED, search, found.t)
    assert found.optimum < search.best_peak


def test_a_speed_limit_finer_than_the_first_pass_s_values_still_finds_the_optimum(arm):
    """r = 2 on the circle (20 intervals): at 0.5 rad/s a held joint cannot move one step of
    the first pass's values per interval (0.35 and 0.70 rad/s), which kept both still and found
    no motion. The pass is repeated on values twice as fine, and finds the optimum at 0.7
    rad/s, whose path moves no joint faster than 0.45 rad/s and so keeps 0.5 too: both
    optima are one, to the last passes' resolution (4e-8 apart)."""
    base, _, _ = arm
    circle = Segment.along(
        "circle", Arc.about([10.0, 4.0], [10.0, 4.0], [6.0, 4.0], "ccw"), 3.5, "trapezoidal", 2.0
    )
    held = ("x3", "x4")
    looser = integral_optimum(base, circle, SQUARED, held, grids=(20,), speeds=0.7)
    assert np.abs(np.diff(looser.x, axis=0)).max() / looser.t[1] < 0.5
    found = integral_optimum(base, circle, SQUARED, held, grids=(20,), speeds=0.5)
    assert np.abs(np.diff(found.x, axis=0)).max() / found.t[1] <= 0.5 + 1e-9
    assert found.optimum == pytest.approx(looser.optimum, rel=1e-6)


def test_the_integral_optimum_refuses_a_peak_objective_and_bad_limits(arm, plain):
    _, robot, circle = arm
    with pytest.raises(InvalidInputError, match="'joint_speeds' is no energy bound"):
        plain.optimum.energy  # noqa: B018 - the property raises
    with pytest.raises(InvalidInputError, match="reduced to its peak; the integral optimum"):
        integral_optimum(robot, circle, "velocity", "x1")
    with pytest.raises(InvalidInputError, match=r"speeds must be one number > 0 or 4 .*got -1"):
        integral_optimum(robot, circle, SQUARED, "x1", speeds=-1)


def test_no_path_found_says_why_and_a_finer_grid_without_one_keeps_the_coarser(arm):
    """An acceleration limit the circle's timing cannot keep leaves no motion on the grid: the
    error says so, and that one would keep the other limits. A finer grid without a path after a
    coarser one with a path keeps the coarser one's motion, marked not converged, with why."""
    _, robot, circle = arm
    pruned = "no motion along segment circle .* one would: the limit is too tight for the task"
    with pytest.raises(InvalidInputError, match=pruned):
        integral_optimum(robot, circle, SQUARED, "x1", grids=(5,), accelerations=1e-3)

    def build(tables, values):  # no path on grids finer than 5 intervals
        x, _, q, usable = tables.at(values)
        return x, q, usable & (len(values) <= 6), _table(np.zeros((len(values), 1, 1)))

    free = np.full(robot.n, np.inf)
    found = _result(
        robot,
        circle,
        "zero",
        "x1",
        *_optimum(robot, circle, "x1", None, (5, 10), build, free, free),
    )
    assert [g.success for g in found.grids] == [True, False] and len(found.t) == 6
    assert found.optimum == 0.0 and not found.converged
    assert "no motion along segment circle" in found.failure


def test_an_optimum_whose_tables_left_out_cells_across_the_fold_is_withheld(arm):
    """Tables that leave out cells across the task's fold cannot follow a motion that crosses
    it, so the optimum may lie above a feasible motion's cost: however well it converged, it is
    no result, and its failure says why; without such cells the refinement rule alone
    decides."""
    _, _, circle = arm
    nodes = np.zeros((3, 4))

    def found(*folded):
        grids = tuple(OptimumGrid(2 * k + 2, 9, 1.0, folded=f) for k, f in enumerate(folded))
        return IntegralOptimum(circle, "zero", "x1", nodes[:, 0], nodes[:, 0], nodes, nodes, grids)

    assert found(0, 0).converged and found(0, 0).failure is None and found(0, 0).folded == 0
    for withheld in (found(5, 0), found(0, 7)):
        assert withheld.change == 0.0 and not withheld.converged and withheld.folded > 0
        assert withheld.failure.startswith("no bound: the tables left out ")
        assert "so a motion that crosses it is not searched" in withheld.failure


def test_the_optimum_keeps_to_the_branch_of_the_improved_start():
    """The slewing 3R arm along a line across its reach, ∫ẋᵀẋ dt (x = q): the improved start
    lies on the elbow inverse kinematics does not pick first. The optimum's first node was
    solved by inverse kinematics, on the other elbow, and the comparison called 0.4042 rad²/s
    its global optimum, above the improved start's 0.2592; on the search's branch it is below
    it, as a least integral over the held histories must be, to the grids' resolution."""
    robot = load_robot(SLEWING / "robot.toml")
    line = WorkCycle.from_toml(SLEWING / "line.toml", dimension=robot.m)["a-b"]
    figures = {f.strategy: f.integral for f in compare(robot, line, SQUARED, "x3").figures}
    assert figures["global optimum"] <= figures["improved start"] * (1 + 1e-3)
    optimum = integral_optimum(
        robot,
        line,
        SQUARED,
        "x3",
        near=improved_start(robot, line, SQUARED, "x3").best_motion.q[0, 0],
    )
    assert robot.same_pose(optimum.q[0], start_configuration(optimum.r[0], -1, line.start), 1e-6)


def test_without_a_branch_the_optimum_is_the_least_over_both_elbows():
    """The slewing 3R arm along the line across its reach (one coarse grid): with no branch
    named, the optimum is the least of both elbows' recursions (each seeded at the start by the
    closed form here), on the elbow that holds it. It was the recursion on the elbow inverse
    kinematics picks first, the higher one: no bound over the held histories."""
    robot = load_robot(SLEWING / "robot.toml")
    line = WorkCycle.from_toml(SLEWING / "line.toml", dimension=robot.m)["a-b"]
    middle, grids = 0.0, (25,)  # x3's stroke is [-2.8, 2.8] rad

    def optimum(near=None):
        return integral_optimum(robot, line, SQUARED, "x3", grids=grids, near=near)

    per_elbow = {e: optimum(start_configuration(middle, e, line.start)) for e in (-1, 1)}
    assert per_elbow[-1].optimum < 0.9 * per_elbow[1].optimum
    found = optimum()
    assert found.optimum == pytest.approx(per_elbow[-1].optimum, rel=1e-12)
    assert robot.same_pose(found.q[0], start_configuration(found.r[0], -1, line.start), 1e-6)
