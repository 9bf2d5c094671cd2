"""Task paths beyond the paper's straight lines: arcs, closed circles and CSV polylines, speed
profiles, the tool's angle as a task coordinate, and the task file that declares them."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from commands import run_cli
from joint_space import fk, jacobian

from redundancy import InvalidInputError, UnreachableError, load_robot
from redundancy.planning.angles import ToolAngleRobot, task_robot, with_tool_angle
from redundancy.planning.ik import check_path, configuration_at
from redundancy.planning.integrate import GAIN, simulate
from redundancy.planning.tasks import (
    Arc,
    Line,
    Polyline,
    Segment,
    WorkCycle,
    read_polyline,
)
from redundancy.resolution.objectives import VELOCITY
from redundancy.resolution.state import actuator_space

ARM = Path(__file__).parent / "data" / "planar4r"


@pytest.fixture(scope="module")
def arm():
    """The planar 4R test arm with x, y and the tool's angle as its task (m = 3, r = 1)."""
    return with_tool_angle(load_robot(ARM / "robot.toml"))


@pytest.fixture(scope="module")
def circle_task():
    base = load_robot(ARM / "robot.toml")
    cycle = WorkCycle.from_toml(ARM / "task.toml", dimension=base.m)
    return task_robot(base, cycle), cycle


def test_a_line_at_constant_speed_is_the_papers_segment():
    segment = Segment.along("1-2", Line(np.array([3.5, -0.5]), np.array([1.0, -0.5])), 0.5)
    assert segment.duration == pytest.approx(5.0)
    np.testing.assert_allclose(segment.velocity_at([0.0, 2.5, 5.0]), [[-0.5, 0.0]] * 3)
    np.testing.assert_allclose(segment.position(2.5), [2.25, -0.5])


def test_an_arc_through_three_points_passes_them_at_constant_speed():
    arc = Arc.through([1.0, 0.0], [0.0, -1.0], [-1.0, 0.0])  # clockwise, through the bottom
    np.testing.assert_allclose(arc.centre, [0.0, 0.0], atol=1e-12)
    assert arc.radius == pytest.approx(1.0) and arc.sweep == pytest.approx(math.pi)
    segment = Segment.along("arc", arc, 0.25)
    t = np.linspace(0.0, segment.duration, 2001)
    y = segment.position(t)
    np.testing.assert_allclose(np.linalg.norm(y, axis=1), 1.0)
    np.testing.assert_allclose(y[1000], [0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(segment.velocity_at(t), axis=1), 0.25)
    numeric = np.gradient(y, t, axis=0, edge_order=2)
    np.testing.assert_allclose(numeric, segment.velocity_at(t), atol=1e-5)


def test_an_arc_in_three_dimensions_lies_on_its_circle():
    arc = Arc.through([1.0, 0.0, 0.0], [0.0, 1.0, 0.5], [-1.0, 0.0, 1.0])
    y = arc.point(np.linspace(0.0, arc.length, 50))
    np.testing.assert_allclose(np.linalg.norm(y - arc.centre, axis=1), arc.radius)
    np.testing.assert_allclose(y[-1], [-1.0, 0.0, 1.0], atol=1e-12)


def test_a_closed_circle_ends_where_it_starts_and_keeps_the_angle():
    circle = Arc.about([1.9, 0.0, 0.5], [1.9, 0.0, 0.5], [1.5, 0.3], "ccw", angles=1)
    assert circle.sweep == pytest.approx(2 * math.pi)
    assert circle.length == pytest.approx(math.pi)  # radius 0.5
    quarter = circle.point(circle.length / 4)
    np.testing.assert_allclose(quarter, [1.5 + 0.3, 0.3 + 0.4, 0.5])  # ccw: towards +y
    np.testing.assert_allclose(circle.point(circle.length), circle.start, atol=1e-12)


def test_an_arc_about_a_centre_needs_its_ends_on_one_circle():
    with pytest.raises(InvalidInputError, match="one distance"):
        Arc.about([1.0, 0.0], [0.0, 2.0], [0.0, 0.0], "ccw")
    with pytest.raises(InvalidInputError, match="on one line"):
        Arc.through([0.0, 0.0], [1.0, 1.0], [2.0, 2.0])


def test_the_trapezoidal_profile_ramps_at_its_acceleration_from_rest_to_rest():
    profile = Segment.along("s", Line([0.0, 0.0], [5.0, 0.0]), 0.5, "trapezoidal", 1.0)
    assert profile.ramp == pytest.approx(0.5)
    assert profile.duration == pytest.approx(5.0 / 0.5 + 0.5)
    t = np.linspace(0.0, profile.duration, 2001)
    s, rate = profile.progress(t)
    assert s[0] == 0 and s[-1] == pytest.approx(5.0)
    assert rate[0] == 0 and rate[-1] == pytest.approx(0.0, abs=1e-12)
    assert rate.max() == pytest.approx(0.5)
    assert np.abs(np.diff(rate) / np.diff(t)).max() <= 1.0 + 1e-9
    np.testing.assert_allclose(np.gradient(s, t, edge_order=2), rate, atol=2e-3)
    # a triangle: never reaches 0.5 m/s
    short = Segment.along("s", Line([0.0, 0.0], [0.1, 0.0]), 0.5, "trapezoidal", 1.0)
    assert short.peak == pytest.approx(math.sqrt(0.1)) and short.duration == pytest.approx(
        2 * math.sqrt(0.1)
    )


def test_the_angle_jacobian_and_its_rate_match_finite_differences(arm):
    rng = np.random.default_rng(4)
    step = 1e-6
    for q in arm.lower * 0.8 + (arm.upper - arm.lower) * 0.8 * rng.random((5, arm.n)):
        space = actuator_space(arm, q)
        numeric = np.array(
            [(fk(arm, q + step * e) - fk(arm, q - step * e)) / (2 * step) for e in np.eye(arm.n)]
        ).T
        np.testing.assert_allclose(space.J[0], numeric, atol=1e-8)
        # a planar arm's tool angle is the sum of its joint angles (the tool along link 4)
        assert space.y[0, 2] == pytest.approx(np.mod(q.sum() + math.pi, 2 * math.pi) - math.pi)
        v = rng.normal(size=arm.n)
        motion = arm.task(arm.kinematics(q[None], v[None]))
        rate = (jacobian(arm, q + step * v) - jacobian(arm, q - step * v)) / (2 * step)
        np.testing.assert_allclose(motion.jacobian_rate[0], rate, atol=1e-7)
        np.testing.assert_allclose(motion.velocity[0], space.J[0] @ v, atol=1e-12)


def test_the_angle_branch_is_centred_where_the_task_asks(arm):
    q = np.array([2.0, 1.2, 0.0, 0.0])  # the tool at 3.2 rad, past π
    assert fk(arm, q)[2] == pytest.approx(3.2 - 2 * math.pi)
    turned = with_tool_angle(arm, centre=math.pi)
    assert fk(turned, q)[2] == pytest.approx(3.2)
    assert isinstance(turned, ToolAngleRobot) and turned.m == 3


def test_a_cycle_s_angle_branch_holds_every_angle_it_passes(tmp_path):
    """170° and 190°, either side of ±180°: the branch is centred at 180°, where it was centred
    at −180° (their circular mean), whose branch (−360°, 0] holds neither, so the start was
    "missed by 6 m"; the motion from 170° to 190° is tracked through 180°. A turn from −60° to
    200° is centred at 70°; a task turning a full turn or more is refused in one line."""
    text = (
        'tool_angle = true\nsegments = ["a-b"]\n[points]\na = [1.9, 0.0, 170]\nb = [1.5, 0.3, A]\n'
    )
    cycle = WorkCycle.from_toml(_task(tmp_path, text.replace("A", "190")), dimension=2)
    assert cycle.angle_centre == pytest.approx(math.pi)
    arm = task_robot(load_robot(ARM / "robot.toml"), cycle)
    motion = _tracked(arm, cycle.segments[0], {"x1": 0.3})
    assert motion.max_tracking_error[0] <= 1e-6
    assert motion.y[0, -1, 2] == pytest.approx(math.radians(190), abs=1e-6)
    turn = WorkCycle.from_toml(_task(tmp_path, text.replace("170", "-60").replace("A", "200")))
    assert turn.angle_centre == pytest.approx(math.radians(70))
    with pytest.raises(InvalidInputError, match="turns from 170° to 530°, a turn or more"):
        WorkCycle.from_toml(_task(tmp_path, text.replace("A", "530")))


def test_the_angle_needs_a_planar_task():
    with pytest.raises(InvalidInputError, match="two task axes"):
        with_tool_angle(load_robot("hiab031_slewing"))


def _tracked(robot, segment, held):
    start = configuration_at(robot, segment.start, held)
    motion = simulate(robot, VELOCITY.resolver, segment, start[None], gain=GAIN, tolerance=1e-7)
    assert not motion.failed[0]
    return motion


def test_position_and_angle_are_tracked_along_an_arc(arm):
    """An arc through three points while the tool turns from 20° to 50°."""
    start, via, end = (
        np.array([1.9, 0.0, math.radians(20)]),
        np.array([1.6, 0.45, 0.0]),
        np.array([1.2, 0.5, math.radians(50)]),
    )
    arc = Arc.through(start, via, end, angles=1)
    segment = Segment.along("arc", arc, 0.3)
    motion = _tracked(arm, segment, {"x1": -0.6})
    assert motion.max_tracking_error[0] <= 1e-6
    assert motion.y[0, -1, 2] == pytest.approx(math.radians(50), abs=1e-6)


def test_position_and_angle_are_tracked_around_a_closed_circle(circle_task):
    robot, cycle = circle_task
    (segment,) = cycle.segments
    assert segment.shape.kind == "arc" and segment.shape.closed
    motion = _tracked(robot, segment, {"x1": -0.9})
    assert motion.max_tracking_error[0] <= 1e-6
    np.testing.assert_allclose(motion.y[0, -1], motion.y[0, 0], atol=1e-6)
    np.testing.assert_allclose(motion.y[0, :, 2], math.radians(30), atol=1e-6)


def _task(tmp_path, text, csv=None, name="task.toml"):
    if csv is not None:
        (tmp_path / "path.csv").write_text(csv)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_task_file_declares_arcs_circles_polylines_angles_and_profiles(tmp_path):
    path = _task(
        tmp_path,
        'name = "every kind"\ntool_angle = true\nspeed = 0.4\nprofile = "trapezoidal"\n'
        'acceleration = 0.8\nheld = ["x1"]\n'
        "segments = [\n"
        '  "a-b",\n'
        '  { from = "b", to = "c", via = "v", speed = 0.2 },\n'
        '  { from = "c", to = "c", centre = "o", direction = "cw", profile = "constant" },\n'
        '  { csv = "path.csv", name = "recorded" },\n'
        "]\n"
        "[points]\na = [1.5, -0.5, 0]\nb = [1.9, 0.0, 10]\nv = [1.7, 0.5, 0]\n"
        "c = [1.2, 0.5, 30]\no = [1.2, 0.2, 0]\n",
        "# recorded on the machine\nx, y, angle\n1.2, 0.5, 30\n1.2, 0.5, 30\n1.4, 0.0, 10\n"
        "1.5, -0.5, 0\n",
    )
    cycle = WorkCycle.from_toml(path, dimension=2)
    assert cycle.tool_angle and [s.name for s in cycle.segments] == [
        "a-b",
        "b-c",
        "c-c",
        "recorded",
    ]
    line, arc, circle, recorded = cycle.segments
    assert line.profile == "trapezoidal" and line.acceleration == 0.8 and line.speed == 0.4
    assert arc.shape.kind == "arc" and arc.speed == 0.2
    assert circle.shape.closed and circle.profile == "constant"
    assert isinstance(recorded.shape, Polyline) and len(recorded.shape.points) == 3  # merged
    np.testing.assert_allclose(recorded.start, [1.2, 0.5, math.radians(30)])
    assert recorded.shape.kinks == pytest.approx((math.hypot(0.2, 0.5),))
    np.testing.assert_allclose(line.velocity_at([0.0, line.duration]), 0.0, atol=1e-12)
    cycle.check_continuous()  # a-b-c-c-a closes


@pytest.mark.parametrize("points", ["", "[points]\n"], ids=["none", "empty"])
def test_a_task_of_polylines_alone_needs_no_points(tmp_path, points):
    path = _task(tmp_path, f'segments = [{{ csv = "path.csv" }}]\n{points}', "1, 0\n2, 0.5\n")
    (segment,) = WorkCycle.from_toml(path, dimension=2).segments
    np.testing.assert_allclose(segment.start, [1, 0])


@pytest.mark.parametrize(
    "text, message",
    [
        ('segments = [{ from = "a" }]\n[points]\na = [0, 0]\n', "missing 'to'"),
        ('segments = [{ from = "a", to = "z" }]\n[points]\na = [0, 0]\n', 'to = "z" must name'),
        (
            'segments = [{ from = "a", to = "b", bend = 1 }]\n[points]\na = [0, 0]\nb = [1, 0]\n',
            "unknown keys \\['bend'\\]",
        ),
        (
            'profile = "trapezoidal"\nsegments = ["a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n',
            'toml: profile = "trapezoidal" needs acceleration',
        ),
        (
            'segments = [{ from = "a", to = "b", profile = "trapezoidal" }]\n[points]\n'
            "a = [0, 0]\nb = [1, 0]\n",
            r"segments\[0\]: segment a-b: a trapezoidal profile needs acceleration > 0 and ≤ 100 "
            r"m/s² \(the tool's maximum\); none given$",
        ),
        (
            'profile = "smooth"\nsegments = ["a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n',
            'profile = "smooth" must be one of "constant", "trapezoidal"',
        ),
        (
            'segments = [{ from = "a", to = "b", centre = "o" }]\n[points]\na = [1, 0]\n'
            "b = [0, 1]\no = [0, 0]\n",
            'needs direction = "ccw" or "cw"',
        ),
        (
            'segments = [{ from = "a", to = "b", centre = "o", direction = "up" }]\n[points]\n'
            "a = [1, 0]\nb = [0, 1]\no = [0, 0]\n",
            r'segments\[0\] direction = "up" must be one of "ccw", "cw"',
        ),
        (
            'tool_angle = true\nsegments = ["a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n',
            "2 coordinates; the robot's task has 3",
        ),
        (
            'tool_angle = "yes"\nsegments = ["a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n',
            'tool_angle = "yes" must be true or false',
        ),
        ('segments = ["a-b", "a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n', "two segments are "),
        ('segment = ["a-b"]\n[points]\na = [0, 0]\nb = [1, 0]\n', "unknown keys \\['segment'\\]"),
        (
            "segments = [3]\n[points]\na = [0, 0]\n",
            "segments = \\[3\\] must be a list of '<from>-<to>' names",
        ),
    ],
)
def test_bad_segments_are_named_in_one_line(tmp_path, text, message):
    with pytest.raises(InvalidInputError, match=message) as raised:
        WorkCycle.from_toml(_task(tmp_path, text), dimension=2)
    assert "\n" not in str(raised.value)


@pytest.mark.parametrize(
    "csv, message",
    [
        ("x,y\n1.0,0.0\n1.5,abc\n", r"path.csv line 3: cell 2 \('abc'\) is not a finite number"),
        ("1.0,0.0\n2_0,1.0\n", r"path.csv line 2: cell 1 \('2_0'\) is not a finite number"),
        ("1.0,0.0\n", r"path.csv: one point \(line 1\); a polyline needs at least two"),
        ("# only this\n1.0,0.0\n", r"one point \(line 2\)"),
        ("1.0,0.0\n1.0,0.0\n", r"one point \(lines 1-2\)"),
        ("1.0,0.0\nnan,1.0\n", r"path.csv line 2: cell 1 \('nan'\) is not a finite number"),
        ("1.0,0.0\n2.0,inf\n", r"path.csv line 2: cell 2 \('inf'\) is not a finite number"),
        # a first line of numbers that are not finite is a bad point, not a line of names
        ("inf,nan\n1.0,0.0\n2.0,1.0\n", r"path.csv line 1: cell 1 \('inf'\) is not a finite"),
        ("x,nan\n1.0,0.0\n2.0,1.0\n", r"path.csv line 1: cell 1 \('x'\) is not a finite"),
        ("1.0,0.0\n2.0,1.0,3.0\n", r"path.csv line 2: 3 values; the task has 2 coordinates"),
        ("1.0,0.0\n1e308,1.0\n", r"path.csv line 2: 1e308 lies beyond ±1000 \(m, or degrees"),
        ("1.0,0.0\n2.0,-1000.5\n", r"path.csv line 2: -1000.5 lies beyond ±1000"),
        ("", r"path.csv: no points"),
    ],
)
def test_a_malformed_polyline_is_one_line_naming_its_line(tmp_path, csv, message):
    (tmp_path / "path.csv").write_text(csv)
    with pytest.raises(InvalidInputError, match=message) as raised:
        read_polyline(tmp_path / "path.csv", 2)
    assert "\n" not in str(raised.value)


def test_a_malformed_polyline_ends_the_command_line_in_one_line(tmp_path):
    path = _task(tmp_path, 'segments = [{ csv = "path.csv" }]\nheld = ["x3"]\n', "1,0\n2,x\n")
    run = run_cli("cycle", "--task", str(path), "--out", str(tmp_path / "out"), "--quiet")
    assert run.returncode == 2
    assert run.stderr.strip().count("\n") == 0
    assert "path.csv line 2: cell 2 ('x') is not a finite number" in run.stderr


def test_a_point_out_of_reach_is_shown_with_its_angle_in_degrees(arm):
    """A task with the tool's angle: the point and its miss are shown in m or mm and degrees,
    the angle never summed into the distance."""
    far = Segment.along("far", Line(np.array([5.0, 0.0, 0.3]), np.array([5.5, 0.0, 0.3]), 1), 0.5)
    with pytest.raises(UnreachableError) as refused:
        check_path(arm, far)
    message = str(refused.value)
    assert f"its point [5.0, 0.0] m at {math.degrees(0.3):.4g}° (t = 0 s)" in message
    assert re.search(r"missed by [\d.]+ mm in position and [\d.]+° in angle$", message)
