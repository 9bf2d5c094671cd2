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

from pathlib import Path

import numpy as np
import pytest

from redundancy import load_robot
from redundancy.errors import InvalidInputError
from redundancy.planning.angles import task_robot
from redundancy.planning.integral_optimum import integral_optimum
from redundancy.planning.starts import improved_start
from redundancy.planning.tasks import Arc, Segment, WorkCycle
from redundancy.resolution.laws import MinVelocityNorm
from redundancy.resolution.objectives import Objective, velocity_norm
from redundancy.resolution.state import ActuatorSpace
from redundancy.study.integral import compare

ARM = Path(__file__).parent / "data" / "kw4r"
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


def _compare(arm, objective):
    _, robot, circle = arm
    return compare(robot, circle, objective, "x1", SPEED, ACCELERATION)


@pytest.fixture(scope="module")
def plain(arm):
    """∫ q̇ᵀq̇ dt three ways."""
    return _compare(arm, SQUARED)


@pytest.fixture(scope="module")
def steered(arm):
    """The same with the obstacle term."""
    return _compare(arm, WITH_OBSTACLE)


def test_the_global_optimum_is_never_above_the_improved_start(plain, steered):
    """On the 4R circle, with and without the obstacle term, the optimum over every history of
    the held first joint lies at or below the improved start's integral, within the optimum's
    discretisation error, which its last refinement bounds (a sequence converging at first
    order or faster moves by less than its last change afterwards); the improved start lies at
    or below the local pseudoinverse from the default start; and the optimum keeps the joints'
    speed and acceleration limits."""
    for comparison in (plain, steered):
        local, improved, optimum = comparison.figures
        found = comparison.optimum
        assert optimum.integral <= improved.integral * (1 + found.change)
        assert improved.integral <= local.integral
        assert optimum.speed <= SPEED + 1e-9 and optimum.acceleration <= ACCELERATION + 1e-9


def test_the_global_optimum_converges_under_refinement(plain, steered):
    """Refining the time grid from 50 to 100 intervals moves the optimum of ∫ q̇ᵀq̇ dt by less
    than 0.5 %. With the obstacle term the joints' speed and acceleration limits bind and the
    optimum is not converged on these grids (it moves by 3 %): it says so."""
    assert [g.intervals for g in plain.optimum.grids] == [50, 100]
    assert plain.optimum.converged and plain.optimum.change < 0.005
    assert not steered.optimum.converged
    optimum = steered.figures[2]
    assert optimum.speed == pytest.approx(SPEED, rel=1e-4)
    assert optimum.acceleration == pytest.approx(ACCELERATION, rel=1e-4)


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
    improved = improved_start(base, circle, SQUARED, held).best.peak
    assert found.optimum <= improved * (1 + found.change)


def test_the_integral_optimum_refuses_a_peak_objective_and_bad_limits(arm):
    _, robot, circle = arm
    with pytest.raises(InvalidInputError, match="reduced to its peak; the integral optimum"):
        integral_optimum(robot, circle, "velocity", "x1")
    with pytest.raises(InvalidInputError, match=r"speeds must be one number > 0 or 4 .*got -1"):
        integral_optimum(robot, circle, SQUARED, "x1", speeds=-1)
