"""Segments follow Eqs. (33)-(34); task files are read with their errors named."""

import numpy as np
import pytest

from redundancy import InvalidInputError, load_robot
from redundancy.model.loading import bundled_root
from redundancy.planning.tasks import Polyline, Segment, WorkCycle


def test_segment_follows_eqs_33_34():
    segment = Segment("1-2", np.array([3.5, -0.5]), np.array([1.0, -0.5]), 0.5)
    assert segment.duration == pytest.approx(5.0)
    np.testing.assert_allclose(
        segment.position([0.0, 2.5, 5.0]), [[3.5, -0.5], [2.25, -0.5], [1.0, -0.5]]
    )
    np.testing.assert_allclose(segment.velocity, [-0.5, 0.0])
    t = np.linspace(0, 5, 11)
    np.testing.assert_allclose(
        np.gradient(segment.position(t), t, axis=0), np.tile(segment.velocity, (11, 1))
    )


def test_the_paper_cycle_ships_with_the_crane():
    cycle = WorkCycle.from_toml(bundled_root() / "hiab031" / "task.toml", dimension=2)
    assert [s.name for s in cycle.segments] == ["1-2", "2-3", "3-1"]
    assert cycle.held == ("x3",)
    np.testing.assert_array_equal(cycle["2-3"].start, [1.0, -0.5])
    np.testing.assert_array_equal(cycle["2-3"].end, [2.25, 3.0])
    assert all(s.speed == 0.5 for s in cycle.segments)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            'segments = ["1-2"]\n[points]\n1 = [0, 0, 0]\n2 = [1, 0, 0]\n',
            "3 coordinates; the robot's task has 2",
        ),
        ('segments = ["1-4"]\n[points]\n1 = [0, 0]\n2 = [1, 0]\n', "points among 1, 2"),
        ('segments = ["1-2"]\n', r"\[points\] table"),
        ('segments = ["1-1"]\n[points]\n1 = [0, 0]\n', "coincide"),
        # closer than a nanometre: one point, as a recorded polyline's repeated points are
        ('segments = ["1-2"]\n[points]\n1 = [1, 0]\n2 = [1.0000000000001, 0]\n', "coincide"),
        (
            'segments = [{ from = "1", to = "2", centre = "o", direction = "ccw" }]\n[points]\n'
            "1 = [1e-10, 0]\n2 = [0, 1e-10]\no = [0, 0]\n",
            "its start lies on its centre",
        ),
        ("not toml [", "not valid TOML"),
    ],
)
def test_bad_task_files_are_named(tmp_path, text, message):
    path = tmp_path / "task.toml"
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=message):
        WorkCycle.from_toml(path, dimension=2)


def test_unknown_segment_lists_the_segments():
    cycle = WorkCycle.from_toml(bundled_root() / "hiab031" / "task.toml")
    with pytest.raises(InvalidInputError, match="segments: 1-2, 2-3, 3-1"):
        cycle["1-3"]


def test_a_task_file_may_start_with_a_byte_order_mark(tmp_path):
    text = (bundled_root() / "hiab031" / "task.toml").read_text()
    path = tmp_path / "task.toml"
    path.write_bytes("\ufeff".encode() + text.encode())
    cycle = WorkCycle.from_toml(path, dimension=2)
    assert [s.name for s in cycle.segments] == ["1-2", "2-3", "3-1"]


def test_a_polyline_takes_nested_lists_and_refuses_what_is_not_a_table_of_points():
    """Points typed as lists are numbers (K, m) like an array's; text, NaN, rows of unequal
    length or a single row are refused in one line that shows them."""
    line = Polyline([[0, 0], [3, 4]])
    assert line.points.dtype == float and line.cumulative[-1] == 5.0
    for points in ([[0, "a"], [1, 1]], [[0, np.nan], [1, 1]], [[0, 0], [1]], [1, 2]):
        with pytest.raises(InvalidInputError, match=r"polyline's points must be \(K, m\) finite"):
            Polyline(points)


def test_a_segment_read_from_a_task_holds_that_task_s_actuators():
    """The Panda's task holds joints 3, 5, 6 and 7; its last four joints, the default without
    a task, leave its shoulder a sphere to move the tool on. A segment or the chain of the
    task's cycle holds the task's by default (a segment held the last four), a segment of
    one's own the last n − m."""
    import warnings

    from redundancy.planning.starts import held_actuators

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its joints driven directly: said where it loads
        panda = load_robot("panda")
    cycle = WorkCycle.from_toml(panda.task_file, dimension=panda.m)
    told = ("panda_joint3", "panda_joint5", "panda_joint6", "panda_joint7")
    assert cycle.held == told
    for path in (cycle, cycle["pick-lift"], cycle.chain()):
        assert held_actuators(panda, path) == told
    own = Segment("own", cycle["pick-lift"].start, cycle["pick-lift"].end, 0.25)
    assert held_actuators(panda, own) == tuple(panda.actuators.names[3:])
