"""The peer strategies on the crane: each runs, tracks the task, and reports its strokes as
they were. pink's tests need the optional `bench` dependencies (pin-pink and a QP solver);
they are skipped without them. Steps of 0.02 s here (0.01 s in the benchmark) keep them quick."""

import sys

import numpy as np
import pytest
from peers import TUNED_GAIN, gradient_projection_run, pseudoinverse_run, tune_gradient_projection
from pink_peer import PinkResolver, pink_run

from redundancy import RedundancyError, actuator_space, load_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.limits import TOLERANCE as LIMIT_TOLERANCE

SEGMENTS = ["1-2", "2-3", "3-1"]
STEP = 0.02


@pytest.fixture(scope="module")
def cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


def honest(run, robot):
    """The run's limit report agrees with its strokes, sample by sample."""
    x = run.trajectory.x[0]
    lower, upper = robot.actuators.lower, robot.actuators.upper
    inside = bool(np.all((x >= lower - LIMIT_TOLERANCE) & (x <= upper + LIMIT_TOLERANCE)))
    violations = run.trajectory.violations(0)
    return run.trajectory.within_limits[0] == inside and (not violations) == inside


@pytest.mark.parametrize("name", SEGMENTS)
@pytest.mark.parametrize("peer", [pseudoinverse_run, gradient_projection_run])
def test_each_resolver_peer_runs_on_the_crane_and_reports_its_limits(crane, cycle, peer, name):
    run = peer(crane, cycle[name], time_step=STEP)
    assert run.trajectory.max_tracking_error[0] < 1e-5
    assert honest(run, crane)


@pytest.mark.parametrize("name", SEGMENTS)
def test_pink_peer_runs_on_the_crane_and_reports_its_limits(crane, cycle, name):
    pytest.importorskip("pink")
    run = pink_run(crane, cycle[name], time_step=STEP)
    assert run.trajectory.max_tracking_error[0] < 1e-3  # one linearised step behind, at most
    assert honest(run, crane)
    assert run.trajectory.within_limits[0]  # pink keeps the joint limits, the strokes' images


def test_plain_pseudoinverse_leaving_a_stroke_is_flagged(crane, cycle):
    """From its default start the plain pseudoinverse takes x1 past its lower limit at the end
    of segment 3-1 (the study's finding); the run says so."""
    run = pseudoinverse_run(crane, cycle["3-1"], time_step=STEP)
    assert not run.trajectory.within_limits[0]
    worst = max(run.trajectory.violations(0), key=lambda v: v.excess)
    assert (worst.actuator, worst.bound) == ("x1", "lower") and worst.excess > 5e-3
    assert not run.summary()["within_limits"] and run.summary()["violations"]


def test_pink_leaving_a_stroke_it_does_not_know_is_flagged(cycle):
    """pink keeps the URDF's joint limits only: with x2's stroke narrowed below its joint's
    range, pink's motion leaves it, and the run reports the excess."""
    pytest.importorskip("pink")
    robot = load_robot("hiab031")
    robot.actuators["x2"].upper = 1.3  # of 1.375 m; pink reaches 1.353 m on segment 1-2
    run = pink_run(robot, cycle["1-2"], time_step=STEP)
    assert not run.trajectory.within_limits[0]
    assert any(v.actuator == "x2" and v.bound == "upper" for v in run.trajectory.violations(0))
    assert honest(run, robot)


def test_tuned_gain_keeps_every_stroke_at_the_least_worst_peak(crane, cycle):
    """Below the tuned gain x1 leaves its stroke on 3-1; above it the peak grows on 1-2."""
    gains = (0.03, TUNED_GAIN, 0.5)
    tuning = tune_gradient_projection(crane, cycle.segments, gains, time_step=STEP)
    assert tuning.chosen == TUNED_GAIN
    assert not tuning.within[0].all() and tuning.within[1:].all()
    assert tuning.peaks[2].max() > tuning.peaks[1].max()


def test_pink_law_tracks_the_task_velocity_to_first_order_in_its_step(crane):
    """pink aims each step at y + ẏ dt through the SE(3) log, linearised: J_H ẋ = ẏ holds to
    O(dt), and tenfold shorter steps make it tenfold closer."""
    pytest.importorskip("pink")
    rng = np.random.default_rng(50)
    q = crane.lower + (crane.upper - crane.lower) * (0.3 + 0.4 * rng.random((10, crane.n)))
    y_dot = rng.normal(scale=0.1, size=(10, crane.m))
    space = actuator_space(crane, q)
    errors = []
    for step in (STEP, STEP / 10):
        x_dot = PinkResolver(crane, step).resolve(space, y_dot)
        errors.append(np.abs(np.einsum("kij,kj->ki", space.J_H, x_dot) - y_dot).max())
    assert errors[0] < 0.01 * np.abs(y_dot).max()
    assert errors[1] < errors[0] / 5


def test_pink_missing_names_the_install(crane, monkeypatch):
    monkeypatch.setitem(sys.modules, "pink", None)
    with pytest.raises(RedundancyError, match="pip install"):
        PinkResolver(crane)
