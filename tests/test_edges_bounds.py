"""Bounds and cycles at the machine's edges: joints driven directly with no stroke (the bound
converges, or is withheld with the solver's reason, never printed below a motion's peak), two
held actuators (the bound, the periodic optimum and the corners' self-motions), and the free
cycle's start labelled as the start it really ran from."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from redundancy import load_robot
from redundancy.planning.angles import task_robot
from redundancy.planning.bound import Transcription, global_optimum, node_times, resampled
from redundancy.planning.cycles import periodic_optimum, plan_cycle, repeat
from redundancy.planning.integrate import simulate
from redundancy.planning.starts import improved_start
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.limits import Limits
from redundancy.resolution.objectives import VELOCITY
from redundancy.resolution.state import evaluate
from redundancy.study.cycles import run_cycle
from redundancy.study.study import run_study
from redundancy.viz.tables import study_table

DATA = Path(__file__).parent / "data"
FIXTURES = Path(__file__).parent / "fixtures" / "intake"
UNBOUNDED = DATA / "unbounded" / "robot.toml"
ARM = DATA / "planar4r"


def _robot_and_task(robot_file: Path, task: Path | None = None):
    robot = load_robot(robot_file)
    return robot, WorkCycle.from_toml(task or robot.task_file, dimension=robot.m)


@pytest.fixture(scope="module")
def unbounded_study():
    """The mini excavator-like arm, boom and stick on continuous joints driven directly, with
    no stroke: both objectives' bounds on both segments."""
    robot, cycle = _robot_and_task(UNBOUNDED)
    assert np.isinf(robot.actuators.lower[:2]).all() and np.isinf(robot.actuators.upper[:2]).all()
    return run_study(robot, cycle, samples=9, progress=False, cycles=0)


def test_an_unbounded_stroke_is_no_constraint_of_the_transcription():
    """Boom and stick have no stroke: the transcription's constraints are the peak's alone, all
    finite (an unbounded end once entered as (x + ∞) / ∞, NaN, and SLSQP stopped after two
    iterations: "Inequality constraints incompatible")."""
    robot, cycle = _robot_and_task(UNBOUNDED)
    segment, intervals = cycle["1-2"], 8
    start = improved_start(robot, segment, VELOCITY, "x3").best_motion.q[:, 0]
    motion = simulate(robot, VELOCITY.resolver, segment, start)
    times = node_times(segment, intervals)
    others = Limits.strokes(robot, ["x1", "x2"])
    guess = resampled(times, motion.t[0], motion.q[0])
    problem = Transcription(robot, VELOCITY, segment, 2, others, intervals, guess)
    z = np.append(resampled(times, motion.t[0], motion.x[0])[:, 2], 1.0)
    constraints, jacobian = problem.constraints(z), problem.jacobian(z)
    assert constraints.shape == (intervals + 1,) and np.isfinite(constraints).all()
    assert jacobian.shape == (intervals + 1, intervals + 2) and np.isfinite(jacobian).all()


def test_bounds_with_unbounded_joints_converge_and_are_never_above_the_improved_peak(
    unbounded_study,
):
    """Every bound of the unbounded arm converges, lies at or below the improved start's peak
    (gap ≥ 0), and is printed as such; none is withheld."""
    report = json.loads(json.dumps(unbounded_study.report(), allow_nan=False))
    bounds = 0
    for entry in report["studies"]:
        for segment in entry["segments"]:
            assert segment["bound_failure"] is None, segment["bound_failure"]
            assert segment["bound"]["converged"]
            assert segment["bound"]["peak"] <= segment["best"]["peak"] * (1 + 1e-4)
            assert segment["gap_percent"] >= -1e-2
            bounds += 1
    assert bounds == 4
    assert "NOT converged" not in study_table(unbounded_study)


def test_a_bound_whose_solver_failed_is_withheld_with_the_solvers_message(unbounded_study):
    """A bound is a result only where it converged: one whose finest grid the solver failed on
    has no peak and no gap in the report or the table, and the solver's message in their
    place."""
    bound = unbounded_study.bounds["velocity"][0]
    failed = dataclasses.replace(
        bound.grids[-1], success=False, message="Inequality constraints incompatible"
    )
    bounds = dict(
        unbounded_study.bounds,
        velocity=(
            dataclasses.replace(bound, grids=(*bound.grids[:-1], failed)),
            *unbounded_study.bounds["velocity"][1:],
        ),
    )
    study = dataclasses.replace(unbounded_study, bounds=bounds)
    segment = study.report()["studies"][0]["segments"][0]
    assert segment["bound"] is None and segment["gap_percent"] is None
    assert "Inequality constraints incompatible" in segment["bound_failure"]
    assert study.gap("velocity", "1-2") is None and study.result("velocity", "1-2") is None
    rows = study_table(study).splitlines()
    row = next(line for line in rows if line.split()[:2] == ["1-2", "velocity"])
    assert row.split()[4:6] == ["-", "-"]
    assert row.endswith(
        f"no bound: NOT converged: the solver failed on the grid of "
        f"{failed.intervals} intervals (Inequality constraints incompatible)"
    )


def test_a_bound_above_the_improved_peak_is_withheld_not_printed_as_a_negative_gap(
    unbounded_study,
):
    """A converged optimum above a feasible motion's peak is a local optimum, not a bound."""
    bound = unbounded_study.bounds["velocity"][1]
    high = [dataclasses.replace(g, peak=g.peak * 1.05) for g in bound.grids]
    bounds = dict(
        unbounded_study.bounds,
        velocity=(unbounded_study.bounds["velocity"][0], dataclasses.replace(bound, grids=high)),
    )
    study = dataclasses.replace(unbounded_study, bounds=bounds)
    assert study.gap("velocity", "2-1") is None
    assert "lies above the improved start's peak" in study.withheld("velocity", "2-1")
    segment = study.report()["studies"][0]["segments"][1]
    assert segment["bound"] is None and "local optimum" in segment["bound_failure"]


@pytest.mark.parametrize("kind", ["continuous", "mimic"])
def test_the_gap_is_never_negative_on_the_intake_fixtures(kind):
    """The test arms read from third-party-like URDFs: the bound is at or below the improved
    start's peak wherever it is a result."""
    robot, cycle = _robot_and_task(FIXTURES / kind / "robot.toml")
    study = run_study(robot, cycle, (VELOCITY,), samples=9, progress=False, cycles=0)
    for segment in cycle.segments:
        gap = study.gap("velocity", segment.name)
        assert (gap is not None and gap >= -1e-2) or study.withheld("velocity", segment.name)


def test_the_bound_on_the_arms_closed_circle_converges_below_the_improved_peak():
    """The 4R arm's circle with the tool's angle (m = 3, r = 1): the finer grid's nodes,
    guessed between the coarser grid's, are reached by continuing from their reached
    neighbours (from the guess alone Newton's method missed the node at t = 8.29 s, and the bound
    failed with "no configuration reaches the task")."""
    base = load_robot(ARM / "robot.toml")
    cycle = WorkCycle.from_toml(ARM / "task.toml", dimension=base.m)
    robot = task_robot(base, cycle)
    circle = cycle.segments[0]
    search = improved_start(robot, circle, VELOCITY, cycle.held)
    bound = global_optimum(robot, circle, VELOCITY, cycle.held, search=search)
    assert bound.converged and bound.bound <= search.best_peak * (1 + 1e-4)
    assert bound.motion.within_limits[0] and bound.motion.max_tracking_error[0] < 1e-9


@pytest.fixture(scope="module")
def two_held():
    """The 4R arm with the tool's position alone (m = 2, n = 4): x3 and x4 held, out along a
    line and back. The plan (sweeps of 16 starts), the bound on the way out and the periodic
    optimum over the cycle."""
    robot, cycle = _robot_and_task(ARM / "robot.toml", ARM / "two_held.toml")
    assert (robot.m, robot.n, cycle.held) == (2, 4, ("x3", "x4"))
    plan = plan_cycle(robot, cycle, VELOCITY, samples=16)
    search = plan.segments[0]
    bound = global_optimum(robot, cycle["a-b"], VELOCITY, cycle.held, grids=(12, 24), search=search)
    periodic = periodic_optimum(robot, cycle, plan.motion, VELOCITY, grids=(16, 32))
    return robot, cycle, plan, bound, periodic


def test_with_two_held_the_bound_lies_between_the_pointwise_least_and_the_best_start(two_held):
    """The bound is never above the best sampled start's peak, and never below the least
    ẋᵀẋ its own nodes allow, ẏᵀ (J_H J_Hᵀ)⁻¹ ẏ (the minimum-norm ẋ with J_H ẋ = ẏ): its ẋ
    tracks the task exactly."""
    robot, cycle, plan, bound, _ = two_held
    search = plan.segments[0]
    assert bound.converged and bound.held == ("x3", "x4") and len(bound.start) == 2
    assert bound.bound <= search.best.peak * (1 + 1e-4)
    assert bound.bound <= search.best_peak * (1 + 1e-4)
    motion = bound.motion
    J_H = evaluate(robot, motion.q[0]).J_H
    y_dot = np.broadcast_to(cycle["a-b"].velocity, (len(J_H), robot.m))
    np.testing.assert_allclose(np.einsum("kij,kj->ki", J_H, motion.x_dot[0]), y_dot, atol=1e-9)
    least = np.einsum("ki,ki->k", y_dot, np.linalg.solve(J_H @ J_H.mT, y_dot[..., None])[..., 0])
    assert bound.bound >= least.max() * (1 - 1e-9)
    assert motion.within_limits[0] and motion.max_tracking_error[0] < 1e-9


def test_with_two_held_the_periodic_optimum_ties_the_cycles_ends_and_closes(two_held):
    robot, cycle, plan, _, periodic = two_held
    assert periodic.held == ("x3", "x4") and periodic.r.shape == (len(periodic.t), 2)
    np.testing.assert_array_equal(periodic.r[0], periodic.r[-1])
    np.testing.assert_allclose(periodic.q[0], periodic.q[-1], atol=1e-9)
    assert periodic.converged
    closed = repeat(robot, cycle, periodic.laws(), periodic.start, 2, "periodic")
    assert np.abs(closed.drift).max() <= 1e-6 and closed.within.all()
    assert closed.score(VELOCITY) == pytest.approx(periodic.peak, rel=0.01)
    assert periodic.peak <= plan.search.best_peak * (1 + 1e-3)


def test_with_two_held_each_corners_self_motion_keeps_the_task_point(two_held):
    """The self-motion between one segment's end and the next one's best start is followed
    along a line of both held actuators; the tool stays at the corner all along."""
    robot, _, plan, _, _ = two_held
    assert len(plan.corners) == 2
    for corner in plan.corners:
        assert corner.reason is None and corner.within_limits
        assert corner.held_delta.shape == (2,) and corner.time > 0
        states = evaluate(robot, corner.path)
        np.testing.assert_allclose(
            states.y, np.broadcast_to(corner.point, states.y.shape), atol=1e-9
        )
        np.testing.assert_allclose(states.x[0], corner.end, atol=1e-9)
        np.testing.assert_allclose(states.x[-1], corner.start, atol=1e-6)


def test_with_two_held_the_cycle_runs_both_strategies_and_says_why_it_has_no_return_map():
    robot, cycle = _robot_and_task(ARM / "robot.toml", ARM / "two_held.toml")
    study = run_cycle(robot, cycle, VELOCITY, cycles=2, samples=16)
    report = study.report()
    assert set(report["strategies"]) == {"free", "periodic"}
    assert report["periodic"]["converged"] and len(report["periodic"]["start_value"]) == 2
    assert max(report["strategies"]["periodic"]["repetition"]["largest_drift_per_cycle"]) <= 1e-6
    assert report["return_map"] is None
    assert "holds 2 (x3, x4)" in report["failures"]["return map"]


def test_a_free_cycle_without_a_feasible_start_runs_from_the_closest_and_says_so():
    """With x1's stroke too short for any start, the free cycle starts where the search came
    closest to keeping it, and its name and report say so (not "whole-cycle improved start")."""
    robot, cycle = _robot_and_task(ARM / "robot.toml", ARM / "two_held.toml")
    x1 = robot.actuators["x1"]
    x1.lower, x1.upper = -0.1, 0.1
    study = run_cycle(robot, cycle, VELOCITY, cycles=1, strategy="free", samples=16)
    search = study.plan.search
    assert search.best is None and study.free_kind == "closest start"
    report = study.report()
    assert report["strategies"]["free"]["name"] == "free, closest start"
    assert report["free_start"].startswith("closest start x3 = ")
    assert str(search.closest_violation) in report["free_start"]
    missed = [s for s in search.samples if s.violations]
    closest = min(missed, key=lambda s: max(v.excess for v in s.violations))
    held = study.repetitions["free"].held_values[0]
    np.testing.assert_allclose(held, closest.values, atol=1e-9)
