"""The toolkit on robots it was not written for: the slewing crane, the Panda, any URDF."""

import warnings

import numpy as np
import pytest
from commands import run_cli

from redundancy import UnreachableError, bundled_robots, load_robot
from redundancy.model.loading import bundled_root
from redundancy.planning.starts import evaluate_starts, improved_start, stroke_box
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.objectives import VELOCITY
from redundancy.study.study import run_study


def quiet_load(name, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Panda declares no actuators
        return load_robot(name, **options)


@pytest.mark.parametrize("name", bundled_robots())
def test_every_bundled_robots_study_runs_and_finds_a_feasible_start(name):
    robot = quiet_load(name)
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    segment = cycle.segments[0]
    study = run_study(
        robot,
        WorkCycle(cycle.name, (segment,), cycle.held),
        (VELOCITY,),
        samples=6,
        bound=False,
        progress=False,
    )
    search = study.searches["velocity"][0]
    assert len(search.held) == robot.n - robot.m
    assert search.best is not None
    motion = search.motion(search.best)
    assert motion.within_limits[0]
    assert motion.max_tracking_error[0] < 1e-4


def test_sampled_search_with_two_held_actuators_is_within_1_percent_of_a_dense_grid():
    """The crane with a one-dimensional task (horizontal tool position): r = 2 held strokes."""
    robot = load_robot("hiab031", task_axes="x")
    segment = Segment("in", np.array([3.0]), np.array([2.0]), 0.5)
    held = ("x2", "x3")
    box = stroke_box(robot, held)
    grid = np.stack(
        np.meshgrid(np.linspace(*box[0], 40), np.linspace(*box[1], 40)), axis=-1
    ).reshape(-1, 2)
    dense = evaluate_starts(robot, segment, VELOCITY, held, grid)
    sampled = improved_start(robot, segment, VELOCITY, held, samples=20)
    assert len(sampled.samples) < len(grid) / 5
    assert sampled.best.peak <= 1.01 * dense.best.peak
    assert sampled.motion(sampled.best).within_limits[0]


def test_the_panda_is_searched_over_four_held_joints():
    robot = quiet_load("panda")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=3)
    search = improved_start(robot, cycle.segments[0], VELOCITY, cycle.held, samples=8)
    assert search.held == ("panda_joint3", "panda_joint5", "panda_joint6", "panda_joint7")
    assert search.values.shape[1] == 4
    assert search.best is not None and len(search.samples) > 8  # refined beyond the design


def test_a_task_point_outside_the_workspace_is_named():
    robot = load_robot("hiab031_slewing")
    segment = Segment("far", np.array([9.0, 0.0, 0.0]), np.array([2.0, 0.0, 1.0]), 0.5)
    with pytest.raises(UnreachableError, match=r"cannot reach the start \[9.0, 0.0, 0.0\]"):
        improved_start(robot, segment, VELOCITY, "x3", samples=4)


def test_the_command_line_takes_a_robot_and_a_task_by_path(tmp_path):
    folder = bundled_root() / "hiab031_slewing"
    task = tmp_path / "task.toml"
    task.write_text(
        'segments = ["a-b"]\nheld = ["x3"]\nspeed = 0.5\n'
        "[points]\na = [3.0, 0.0, -0.3]\nb = [2.2, 0.0, 1.8]\n"
    )
    run = run_cli(
        "study",
        "--robot",
        str(folder / "robot.toml"),
        "--task",
        str(task),
        "--samples",
        "4",
        "--objective",
        "velocity",
        "--quiet",
        "--out",
        str(tmp_path / "out"),
    )
    assert run.returncode == 0, run.stderr
    assert "a-b" in run.stdout and "improved, velocity objective" in run.stdout
    assert (tmp_path / "out" / "report.json").is_file()


def test_a_task_of_the_wrong_dimension_is_refused_on_the_command_line(tmp_path):
    task = tmp_path / "task.toml"
    task.write_text('segments = ["a-b"]\n[points]\na = [3.0, -0.3]\nb = [2.2, 1.8]\n')
    run = run_cli(
        "study",
        "--robot",
        "hiab031_slewing",
        "--task",
        str(task),
        "--quiet",
        "--out",
        str(tmp_path / "out"),
    )
    assert run.returncode == 2
    assert "point a has 2 coordinates; the robot's task has 3" in run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["task.toml"]
