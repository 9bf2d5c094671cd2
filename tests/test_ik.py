"""Inverse kinematics with held actuators: round trips, branch choice, and unreachable points."""

import re
from pathlib import Path

import numpy as np
import pytest
from hiab031_closed_form import tool
from slewing3r_closed_form import shoulder_held_configuration, slew_held_configuration

from redundancy import (
    InvalidInputError,
    Segment,
    UnreachableError,
    actuator_space,
    load_robot,
)
from redundancy.model.robot import Robot
from redundancy.model.values import modulo_turn
from redundancy.planning.ik import (
    CONTINUATION_ITERATIONS,
    _seeds,
    check_path,
    configuration_at,
    continue_held,
    fold_side,
    inverse_kinematics,
    newton,
)
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.state import evaluate


def test_round_trip_reaches_the_point_with_the_held_actuator_at_its_value(crane):
    rng = np.random.default_rng(40)
    values = rng.uniform(0.9, 1.09, size=(20, 1))
    point = np.array([3.5, -0.5])
    solution = inverse_kinematics(crane, point, ["x3"], values)
    assert solution.reached.all()
    # checked against the paper's closed form (Eqs. 4-5, 9), not the solver's own model
    for q, value in zip(solution.q, values[:, 0]):
        assert np.linalg.norm(tool(q) - point) <= 1e-9
        assert abs(actuator_space(crane, q).x[0, 2] - value) <= 1e-9
        assert np.all((q >= crane.lower) & (q <= crane.upper))


def test_the_branch_inside_the_joint_limits_is_chosen(crane):
    q = configuration_at(crane, [2.25, 3.0], {"x3": 0.3})
    assert np.all((q >= crane.lower) & (q <= crane.upper))
    # the other branch (boom 2 folded the other way) has q2 < 0, outside [12.4°, 137.6°]
    assert q[1] > 0


@pytest.mark.parametrize("elbow", [1, -1])
def test_continuation_along_the_held_value_keeps_to_its_elbow(elbow, monkeypatch):
    """The slewing 3R arm's line start with its slew x1 held, continued from one elbow at
    x1 = −122° to 24 values across its reach at once: every configuration is that elbow's (the
    closed form's). Newton from the far start landed on the other elbow at 5 of them from the
    elbow up (q3 > 0), so a search along x1 mixed both. The core's loop on the Python pass (a
    kind of your own) gives the same configurations, residuals and sides to the last bit."""
    slewing = Path(__file__).parent / "data" / "slewing3r"
    robot = load_robot(slewing / "robot.toml")
    point = WorkCycle.from_toml(slewing / "line.toml", dimension=robot.m)["a-b"].start
    start, values = np.radians(-122.0), np.radians(np.linspace(-191.0, -65.0, 24))
    seed = slew_held_configuration(start, elbow, point)[None]
    known = (np.array([start]), seed, fold_side(evaluate(robot, seed), [0]))
    q, residual, sides = continue_held(robot, point, 0, known, values)  # joint ranges not kept
    assert np.all(residual < 1e-9)
    assert np.array_equal(sides, np.full(len(values), known[2][0]))
    for v, found in zip(values, q):  # every joint an angle: one pose modulo a turn each
        apart = modulo_turn(found - slew_held_configuration(v, elbow, point))
        assert np.abs(apart).max() < 1e-9
    monkeypatch.setattr(Robot, "held_pass", lambda robot, part: None)
    for mine, python in zip((q, residual, sides), continue_held(robot, point, 0, known, values)):
        assert np.array_equal(mine, python)


def test_continuation_takes_a_slew_a_turn_back_inside_its_stroke(monkeypatch):
    """The slewing 3R arm with a slew of one turn's range, [−3.14159, 3.14159], its shoulder x2
    held, at the line's start on elbow −1: the closed form's slew falls from −2.98 rad at
    x2 = 0.3 to −3.38 at 1.2, past the range's end beyond x2 ≈ 0.65. Continued from x2 = 0.3,
    every start is the closed form's pose with the slew inside its range, a turn up where the
    closed form's is below it, on the side of the fold it started from. The core's loop on the
    Python pass (a kind of your own) gives the same bits."""
    robot = load_robot(Path(__file__).parent / "data" / "slewing3r" / "slew_held.toml")
    point = np.array([-1.3948182450898194, -0.919903416871264])
    seed = shoulder_held_configuration(0.3, -1, point)[None]
    known = (np.array([0.3]), seed, fold_side(evaluate(robot, seed), [1]))
    values = np.linspace(0.35, 1.2, 18)
    exact = np.array([shoulder_held_configuration(v, -1, point) for v in values])
    below = exact[:, 0] < robot.lower[0]
    assert 5 <= below.sum() < len(values)
    exact[below, 0] += 2 * np.pi
    q, residual, sides = continue_held(robot, point, 1, known, values)
    assert np.all(residual < 1e-9) and np.all(sides == known[2][0])
    assert np.abs(q - exact).max() < 1e-9
    monkeypatch.setattr(Robot, "held_pass", lambda robot, part: None)
    for python, mine in zip(continue_held(robot, point, 1, known, values), (q, residual, sides)):
        assert np.array_equal(python, mine)


@pytest.mark.parametrize("compiled", [True, False])
def test_newton_gives_the_side_of_the_fold_of_its_solution(compiled, monkeypatch):
    """With its slew held, the slewing 3R arm's K = [J; A_h] has the row e₁ᵀ under the task's
    two: det K = det [∂y/∂q2, ∂y/∂q3] = 0.8 · 0.5 · sin q3 (the last two links' closed form),
    so the side of the fold Newton gives with each solution is its elbow, sign q3. Newton
    starts 0.05 rad off the closed form's configuration at 12 slews across its reach, elbow up
    and down, on the core's pass of the task and the slew, and on the Python one (a kind of
    your own); the side is also `fold_side` of the state evaluated there."""
    if not compiled:
        monkeypatch.setattr(Robot, "held_pass", lambda robot, part: None)
    slewing = Path(__file__).parent / "data" / "slewing3r"
    robot = load_robot(slewing / "robot.toml")
    point = WorkCycle.from_toml(slewing / "line.toml", dimension=robot.m)["a-b"].start
    values = np.radians(np.linspace(-180.0, -70.0, 12))
    for elbow in (1, -1):
        exact = np.array([slew_held_configuration(v, elbow, point) for v in values])
        target = np.column_stack([np.tile(point, (len(values), 1)), values])
        solved = newton(robot, exact + 0.05, [0], target, CONTINUATION_ITERATIONS)
        assert np.all(solved.miss < 1e-9)
        assert np.abs(modulo_turn(solved.q - exact)).max() < 1e-9
        assert np.array_equal(solved.side, np.full(len(values), float(elbow)))
        assert np.array_equal(solved.side, fold_side(evaluate(robot, solved.q), [0]))


def test_unreachable_point_says_by_how_much(crane):
    # joint 1 at (-0.228, 0.957); with x3 = 0.5 the tool reaches at most ~3.73 m from it
    with pytest.raises(
        UnreachableError, match=r"\[6.0, 3.0\] with x3 = 500 mm.*misses it by 28\d\d mm"
    ):
        configuration_at(crane, [6.0, 3.0], {"x3": 0.5})


def test_holding_the_wrong_number_of_actuators_is_refused(crane):
    with pytest.raises(InvalidInputError, match="n − m = 1 redundant"):
        configuration_at(crane, [2.0, 1.0], {"x2": 1.0, "x3": 0.5})
    with pytest.raises(InvalidInputError, match="unknown actuators"):
        configuration_at(crane, [2.0, 1.0], {"x4": 1.0})


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize("name", ["hiab031", "hiab031_slewing", "panda"])
def test_check_path_accepts_every_bundled_task(name):
    robot = load_robot(name)
    for segment in WorkCycle.from_toml(robot.task_file, dimension=robot.m).segments:
        check_path(robot, segment)


def test_check_path_refuses_a_segment_that_leaves_the_workspace_between_reachable_ends(crane):
    start, end = np.array([0.0, -1.0]), np.array([2.0, 3.0])
    for point in (start, end):  # both ends are reached, by a configuration inside the limits
        check_path(crane, Segment("end", point, point + 1e-3, 0.5))
    with pytest.raises(UnreachableError) as refused:
        check_path(crane, Segment("a-b", start, end, 0.5))
    numbers = [float(v) for v in re.findall(r"-?\d+\.?\d*", str(refused.value).split("[")[1])[:2]]
    on_segment = start + (end - start) * ((np.array(numbers) - start) @ (end - start)) / (
        (end - start) @ (end - start)
    )
    assert np.allclose(numbers, on_segment)  # the point named lies on the segment


def test_a_path_out_to_where_joints_reach_their_limits_is_accepted(crane):
    """The crane's farthest reach along y2 = −0.5 m has the boom at its lower limit and the
    telescope out at its upper one, the stick's angle solved from Eqs. (4)-(5): 3.8234 m. A
    path out to 1 mm short of it is followed (joints held at their limits while the others
    step), and one 1 mm past it is refused."""
    from scipy.optimize import brentq

    q1, d3 = crane.lower[0], crane.upper[2]
    q2 = brentq(lambda q2: tool([q1, q2, d3])[1] + 0.5, crane.lower[1], crane.upper[1])
    farthest = tool([q1, q2, d3])[0]
    assert farthest == pytest.approx(3.823423, abs=1e-6)
    start = np.array([3.5, -0.5])
    check_path(crane, Segment("edge", start, np.array([farthest - 1e-3, -0.5]), 0.5))
    with pytest.raises(UnreachableError, match="out of reach"):
        check_path(crane, Segment("edge", start, np.array([farthest + 1e-3, -0.5]), 0.5))


@pytest.mark.parametrize("name", ["hiab031", "hiab031_slewing"])
def test_ik_seeds_are_roberts_sequence_inside_the_joint_box(name):
    """Every seed 5 % inside the box; the ratio φ solves φ^(n+1) = φ + 1 and steps joint j by
    φ^(−j); each joint's seeds are then a Kronecker sequence, whose gaps around the circle take
    at most three lengths (the three-gap theorem): evenly spread, with no cluster."""
    robot = load_robot(name)
    lower, upper = robot.span
    unit = (_seeds(robot, 100) - lower) / (upper - lower)
    assert unit.min() >= 0.05 - 1e-12 and unit.max() <= 0.95 + 1e-12
    u = (unit - 0.05) / 0.9
    alpha = np.mod(u[1] - u[0], 1.0)
    phi = 1 / alpha[0]
    assert phi ** (robot.n + 1) == pytest.approx(phi + 1, rel=1e-12)
    np.testing.assert_allclose(alpha, phi ** -np.arange(1.0, robot.n + 1), rtol=1e-12)
    for column in np.sort(u, axis=0).T:
        gaps = np.diff(np.append(column, column[0] + 1))
        assert len(np.unique(np.round(gaps, 9))) <= 3


def test_newton_on_the_compiled_pass_is_newton_on_the_python_one(crane, monkeypatch):
    """The core's Newton loop reaches the same configurations, to rounding, on the compiled pass
    of the task and the held actuator (`Robot.held_pass`) as on the Python one (what a kind of
    your own runs on): from the same seeds, with the same rows shared and stopped."""
    values = np.linspace(0.0, 1.2, 13)[:, None]  # some held values the crane cannot reach
    point = np.array([3.5, -0.5])
    compiled = inverse_kinematics(crane, point, ["x3"], values, seeds=16)
    monkeypatch.setattr(Robot, "held_pass", lambda robot, part: None)
    python = inverse_kinematics(crane, point, ["x3"], values, seeds=16)
    np.testing.assert_array_equal(compiled.reached, python.reached)
    assert compiled.reached.any() and not compiled.reached.all()
    np.testing.assert_allclose(compiled.q, python.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.miss, python.miss, rtol=1e-9, atol=1e-12)  # TOLERANCE
