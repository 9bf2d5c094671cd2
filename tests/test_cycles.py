"""Work cycles as a machine runs them: continuous through the corners, the whole-cycle improved
start beside the per-segment plan, repetition and drift, and the drift-free periodic strategy."""

import html
import itertools
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from commands import run_cli
from geared import GearedMotor
from slewing3r_closed_form import start_configuration

from redundancy import InvalidInputError, load_robot
from redundancy.model.loading import bundled_root
from redundancy.planning.angles import task_robot
from redundancy.planning.bound import (
    Transcription,
    differentiation,
    global_optimum,
    node_intervals,
)
from redundancy.planning.cycles import (
    ROUNDING,
    SETTLED,
    TASK_GAIN,
    FixedPoint,
    ReturnMap,
    _corner,
    gap_speed,
    improved_cycle_start,
    periodic_optimum,
    plan_cycle,
    repeat,
    return_map,
    settling,
)
from redundancy.planning.integrate import simulate
from redundancy.planning.motions import simulate_path
from redundancy.planning.starts import Configurations, evaluate_starts, improved_start
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.limits import Limits, amount
from redundancy.resolution.objectives import ENERGY, VELOCITY
from redundancy.resolution.state import evaluate
from redundancy.study.cycles import repetition_report, run_cycle
from redundancy.viz.tables import cycle_table, fixed_point_words

ARM = Path(__file__).parent / "data" / "planar4r"
SLEWING = Path(__file__).parent / "data" / "slewing3r"
ARM3 = Path(__file__).parent / "data" / "arm3"


@pytest.fixture(scope="module")
def circle():
    """The planar 4R arm written for these tests on a closed circle with the tool's angle:
    x, y and the angle, m = 3, n = 4, r = 1."""
    base = load_robot(ARM / "robot.toml")
    cycle = WorkCycle.from_toml(ARM / "task.toml", dimension=base.m)
    robot = task_robot(base, cycle)
    assert (robot.m, robot.n) == (3, 4)
    return robot, cycle


@pytest.fixture(scope="module")
def arm_runs(circle):
    """The free pseudoinverse and the drift-free periodic strategy, 20 cycles each."""
    robot, cycle = circle
    search = improved_cycle_start(robot, cycle, VELOCITY)
    motion = search.motion()
    free = repeat(robot, cycle, VELOCITY.resolver, motion.q[0, 0], 20)
    periodic = periodic_optimum(robot, cycle, motion)
    closed = repeat(robot, cycle, periodic.laws(), periodic.start, 20, "periodic")
    return search, motion, free, periodic, closed


@pytest.fixture(scope="module")
def crane_study(paper_study):
    """The crane's cycle study, 3 cycles: the paper study's cycle section (conftest), which is
    `run_cycle(crane, paper_cycle, VELOCITY, cycles=3)`."""
    return paper_study.cycle_study


def test_the_free_pseudoinverse_drifts_on_the_closed_circle(arm_runs):
    _, _, free, _, _ = arm_runs
    largest = np.abs(free.drift).max(axis=1)
    assert largest[0] > 1e-3  # far above the integrator's error
    report = repetition_report(free)
    assert len(report["largest_drift_per_cycle"]) == 20
    assert report["largest_drift_per_cycle"][0] == pytest.approx(largest[0])
    assert set(report["drift_per_cycle"]) == {"x1", "x2", "x3", "x4"}
    assert max(report["tool_drift_per_cycle"]) < 1e-5  # the task closes; the self-motion not


def test_the_drift_free_strategy_closes_every_cycle_within_1e_6(arm_runs):
    _, _, _, periodic, closed = arm_runs
    assert closed.cycles == 20
    assert np.abs(closed.drift).max() <= 1e-6
    assert closed.tool_drift.max() <= 1e-6
    assert closed.within.all()
    assert closed.settling.settles and closed.settling.settled_at == 1
    # in words with its unit: the arm's actuators are its joints, which turn
    assert repetition_report(closed)["settling"] == "closed (drift below 1e-06 rad) from cycle 1"
    assert periodic.converged
    # the machine runs the plan: its first cycle's peak is the plan's to a per cent
    assert closed.score(VELOCITY) == pytest.approx(periodic.peak, rel=0.01)


def test_the_periodic_plan_is_periodic_and_keeps_the_strokes(arm_runs, circle):
    robot, _ = circle
    _, _, _, periodic, _ = arm_runs
    assert periodic.r[0] == periodic.r[-1]
    np.testing.assert_allclose(periodic.q[0], periodic.q[-1], atol=1e-9)
    limits = Limits.strokes(robot)
    assert limits.margin(evaluate(robot, periodic.q).x).min() > 0


@pytest.mark.parametrize("ratio", [None, 2.5], ids=["driven directly", "through a gear"])
def test_a_slew_that_turns_once_around_a_cycle_does_not_drift(tmp_path, ratio):
    """The slewing crane with a continuous slew joint and no slew stroke, following a full
    circle about its column: each cycle turns the slew by 2π and leaves the machine as it
    found it. Its drift is taken modulo a turn, ~1e-8 rad as the others', and the repetition
    closes (it counted 2π of drift a cycle and never settled). So is the per-segment plan's
    change at a corner, where the slew ends one half at π and starts the next at −π, one pose:
    no change, and the corner's self-motion ends at the next start (it said 2π, and another
    branch). Driven through a gear of a user's own kind, x = 2.5 q, a turn of the joint is
    5π of the motor, and 2π of the motor is no turn: it was taken modulo 2π, as an angle of
    the joint's own, and drifted π a cycle unseen."""
    urdf = (bundled_root() / "hiab031_slewing" / "hiab031_slewing.urdf").read_text()
    urdf = urdf.replace(
        '<joint name="slew_joint" type="revolute">', '<joint name="slew_joint" type="continuous">'
    )
    urdf = re.sub(r'<transmission name="slew">.*?</transmission>', "", urdf, flags=re.S)
    (tmp_path / "crane.urdf").write_text(urdf)
    geared = f'[actuators.slew]\nkind = "GearedMotor"\njoint = "slew_joint"\nratio = {ratio}\n'
    (tmp_path / "robot.toml").write_text(
        'urdf = "crane.urdf"\ntool_frame = "tool"\ntask_axes = "xyz"\npayload = 100.0\n'
        + (geared if ratio else "")
    )
    (tmp_path / "task.toml").write_text(
        'name = "circle"\nspeed = 0.5\nheld = ["x3"]\nsegments = [\n'
        '  { from = "a", to = "b", via = "n", name = "half1" },\n'
        '  { from = "b", to = "a", via = "s", name = "half2" },\n]\n'
        "[points]\na = [2.5, 0.0, 0.5]\nb = [-2.5, 0.0, 0.5]\nn = [0.0, 2.5, 0.5]\n"
        "s = [0.0, -2.5, 0.5]\n"
    )
    if ratio:
        crane = load_robot(tmp_path / "robot.toml")
        slew = crane.actuators["slew"]
        assert isinstance(slew, GearedMotor)
    else:
        with pytest.warns(UserWarning, match=r"driven directly \(Identity\): slew_joint"):
            crane = load_robot(tmp_path / "robot.toml")
        slew = crane.actuators["slew_joint"]
    turn = 2 * np.pi * (ratio or 1)  # x(q + 2π e_slew) − x(q), by x = ratio q
    assert slew.rotary and slew.lower == -np.inf and slew.upper == np.inf
    np.testing.assert_allclose(crane.actuator_turns, [turn, 0, 0, 0], rtol=1e-12, atol=1e-12)
    change = np.array([[turn + 0.1, 0, 0, 0], [2 * np.pi, 0.5, 0, 0]])
    np.testing.assert_allclose(crane.turned(change)[:, 0], [0.1, 2 * np.pi if ratio else 0])
    cycle = WorkCycle.from_toml(tmp_path / "task.toml", dimension=crane.m)
    plan = plan_cycle(crane, cycle, VELOCITY)
    first, second = plan.segment_motions
    raw = [abs(second.x[0, 0, 0] - first.x[0, -1, 0]), abs(first.x[0, 0, 0] - second.x[0, -1, 0])]
    assert max(raw) == pytest.approx(turn)  # the two halves' starts a turn apart
    for corner in plan.corners:
        assert abs(corner.delta[0]) < 1e-9 and corner.within_limits and corner.reason is None
    repetition = repeat(crane, cycle, VELOCITY.resolver, plan.motion.q[0, 0], cycles=3)
    np.testing.assert_allclose(np.diff(repetition.x[:, 0]), turn, atol=1e-6)
    assert np.abs(repetition.drift).max() < 1e-6
    assert repetition.settling.settles


def test_the_drift_is_read_as_a_limit_cycle_or_not():
    """Settling towards a limit cycle is read from the return map's stable fixed point the
    repetition heads for, not from the drifts' trend alone."""
    values = 1.0 + 0.5 ** np.arange(12) * 1e-2  # halving steps: converging
    drift = np.diff(values)[:, None]
    found = settling(values, drift, [FixedPoint(1.0, 0.5, True)])
    assert found.settles and found.contraction == pytest.approx(0.5)
    assert found.limit == pytest.approx(1.0, abs=1e-9)
    # the last drift, 0.5¹¹ 1e-2 = 4.9e-6, halved per cycle (P' = 0.5) to 1e-6: 2.3 more cycles
    assert found.cycles_to_settle == 3
    # a map contracting slowly, P(v) = v* + 0.93 (v − v*): the forecast after three cycles is
    # the count of further cycles whose drift the map itself brings below SETTLED
    star, slope = 0.8278, 0.93
    values = star + 9e-3 * slope ** np.arange(4)
    forecast = settling(values, np.diff(values)[:, None], [FixedPoint(star, slope, True)])
    v, more = values[-1], 0
    while abs((star + slope * (v - star)) - v) > SETTLED:
        v, more = star + slope * (v - star), more + 1
    assert forecast.cycles_to_settle == more + 1  # the cycle whose drift is below it
    growing = 1.0 + 1.5 ** np.arange(12) * 1e-3
    assert not settling(growing, np.diff(growing)[:, None], [FixedPoint(1.0, 0.5, True)]).settles
    still = np.full(5, 0.3)
    assert settling(still, np.zeros((4, 1))).settled_at == 1
    assert SETTLED == 1e-6


def test_q_is_continuous_at_every_corner_of_the_cranes_cycle(crane, paper_cycle, crane_study):
    """The cycle's motion is one trajectory in cycle time: one sample at each corner, on the
    corner's point, and q moves no further across a corner than in any other sample's step."""
    motion = crane_study.plan.motion
    t, q = motion.t[0], motion.q[0]
    steps = np.abs(np.diff(q, axis=0)).max(axis=1)
    for offset, segment in zip(paper_cycle.chain().offsets[1:-1], paper_cycle.segments[1:]):
        (corner,) = np.flatnonzero(np.abs(t - offset) < 1e-12)
        np.testing.assert_allclose(motion.y[0, corner], segment.start, atol=1e-4)
        assert steps[corner] <= 1.5 * max(steps[corner - 1], steps[corner + 1])
    np.testing.assert_allclose(motion.y[0, -1], motion.y[0, 0], atol=1e-4)


def _tool_velocity(motion, row, sample):
    space = evaluate(motion.robot, motion.q[0, sample][None])
    return (space.J_H @ motion.x_dot[0, sample][:, None])[0, :, 0]


def test_with_trapezoidal_profiles_the_tool_velocity_is_continuous_at_the_corners(
    crane, paper_cycle
):
    jumps = {}
    for profile in ("constant", "trapezoidal"):
        segments = tuple(
            replace(s, profile=profile, acceleration=0.5) for s in paper_cycle.segments
        )
        cycle = replace(paper_cycle, segments=segments)
        q = Configurations.branches(crane, segments[0], "x3")[0].at(np.array([0.82])).q
        pieces = []  # each segment from where the one before ended, as the cycle runs them
        for segment in cycle.segments:
            pieces.append(simulate(crane, VELOCITY.resolver, segment, q, gain=20.0))
            q = pieces[-1].q[:, -1]
        gaps = []
        for before, after in itertools.pairwise(pieces):
            gaps.append(np.linalg.norm(_tool_velocity(before, 0, -1) - _tool_velocity(after, 0, 0)))
        jumps[profile] = max(gaps)
    assert jumps["trapezoidal"] < 1e-9
    assert jumps["constant"] > 0.3  # the paper's constant speed turns 0.5 m/s at a corner


def test_the_whole_cycle_improved_start_keeps_every_stroke_over_the_full_cycle(
    crane, paper_cycle, crane_study
):
    search = crane_study.plan.search
    assert search.best is not None and search.best.feasible
    lowest, highest = search.feasible_range
    assert 0.78 < lowest < highest < 0.86  # far narrower than any one segment's
    motion = search.motion()
    assert motion.within_limits[0] and motion.margins[0] >= 0
    assert not motion.violations(0)
    assert motion.score(VELOCITY)[0] == pytest.approx(search.best.peak, rel=1e-3)
    # segment 1-2's own best start, x3 = 1.09, passes a stroke later in the cycle
    own = crane_study.plan.segments[0].best.values[0]
    assert own == pytest.approx(1.09, abs=1e-3)
    chain = paper_cycle.chain()
    later = evaluate_starts(
        crane,
        chain,
        VELOCITY,
        "x3",
        Configurations.branches(crane, chain, "x3")[0].at(np.array([own])),
    )
    assert not later.samples[0].feasible and later.samples[0].violations


def test_the_report_lists_the_corners_self_motion_gaps(crane_study):
    report = json.loads(json.dumps(crane_study.report(), allow_nan=False))
    corners = report["per_segment"]["corners"]
    assert [(c["after"], c["before"]) for c in corners] == [
        ("1-2", "2-3"),
        ("2-3", "3-1"),
        ("3-1", "1-2"),
    ]
    plan = crane_study.plan
    names = [s.name for s in plan.cycle.segments]
    for corner, entry in zip(plan.corners, corners):
        end = plan.segment_motions[names.index(corner.after)]
        before = plan.segments[names.index(corner.before)]
        assert entry["held_delta"]["x3"] == pytest.approx(
            before.best.values[0] - end.x[0, -1, 2], abs=1e-9
        )
        assert entry["speed"] == 0.25  # the telescope cylinder's maximum speed
        assert entry["time_s"] == pytest.approx(abs(entry["held_delta"]["x3"]) / 0.25)
        assert set(entry["delta"]) == {"x1", "x2", "x3"}
    assert abs(corners[0]["held_delta"]["x3"]) > 0.1  # 1-2 ends far from 2-3's best start
    assert report["per_segment"]["self_motion_time_s"] == pytest.approx(
        sum(c["time_s"] for c in corners)
    )
    assert "1-2 → 2-3" in cycle_table(crane_study)


def test_the_cranes_cycle_reports_drift_and_the_drift_free_price(crane_study):
    report = crane_study.report()
    free = report["strategies"]["free"]["repetition"]
    periodic = report["strategies"]["periodic"]["repetition"]
    assert max(free["largest_drift_per_cycle"]) > 1e-4
    assert max(periodic["largest_drift_per_cycle"]) <= 1e-6
    assert free["first_cycle_past_a_limit"] is None
    price = report["periodic_versus_free_percent"]
    assert set(price) == {"objective", "ls_energy_kj", "cp_energy_kj"}
    for name in ("free", "periodic"):
        strategy = report["strategies"][name]
        assert strategy["within_limits"] and strategy["ls_energy_kj"] > 0
    assert report["strategies"]["periodic"]["objective"] < report["strategies"]["free"]["objective"]


def test_a_periodic_plan_that_did_not_converge_is_said_not_shown_optimal(crane_study):
    """The drift-free strategy's motions compare with the free cycle's whatever its plan; where
    the periodic optimum's last refinement moved it by 0.5 % or more, the table and the page
    say its plan is not shown optimal (a review's forwarder crane: 3.7 %, printed as a plain
    −33 %)."""
    from redundancy.viz.report import _cycle_body
    from redundancy.viz.tables import cycle_table

    assert crane_study.periodic.converged
    assert "not shown optimal" not in cycle_table(crane_study)
    coarse, fine = crane_study.periodic.grids[-2:]
    moved = replace(coarse, peak=fine.optimum * 1.037)
    unconverged = replace(crane_study, periodic=replace(crane_study.periodic, grids=(moved, fine)))
    line = cycle_table(unconverged).splitlines()[-2]
    assert line.startswith("drift-free against") and "not shown optimal: NOT converged" in line
    page = _cycle_body(json.loads(json.dumps(unconverged.report(), allow_nan=False)))
    assert "The periodic plan is not shown optimal: NOT converged, change 3.70 %" in page


def test_the_return_map_finds_the_free_cycles_limit_cycle(crane, paper_cycle, crane_study):
    mapped = crane_study.map
    ((value, slope, _),) = mapped.fixed_points
    assert 0.80 < value < 0.86 and 0 < slope < 1  # stable
    # the repetition converges towards it: each cycle's drift points at the fixed point
    free = crane_study.repetitions["free"]
    held = free.held_values[:, 0]
    assert np.all(np.sign(np.diff(held)) == np.sign(value - held[:-1]))
    again = return_map(crane, paper_cycle, VELOCITY.resolver, "x3", values=np.array([value]))
    assert again.following[0] == pytest.approx(value, abs=2e-4)


@pytest.fixture(scope="module")
def slewing_study():
    """The 3R arm slewing its tool once around its base, x3 held: from the plan's start the
    first cycle flips the arm to the other elbow, where the held value contracts to 0 by about
    0.17 a cycle. Both strategies, six cycles."""
    robot = load_robot(SLEWING / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    return run_cycle(robot, cycle, VELOCITY, cycles=6)


@pytest.mark.parametrize("rounding", [-1e-12, 1e-12])
def test_a_fixed_point_on_a_sample_has_the_maps_slope_whichever_side_rounding_puts_it(rounding):
    """P(v) = 0.178 v + 0.3 v² sampled every 0.157 with its fixed point v* = 0 on a sample,
    where P(v*) − v* is a rounding error of either sign: the slope is P'(0) = 0.178 of the
    parabola through the samples, for both signs. The secant of the interval the sign change
    fell in gave 0.131 or 0.225."""
    values = 0.157 * np.arange(-4, 5)
    following = 0.178 * values + 0.3 * values**2
    following[4] = rounding
    mapped = ReturnMap("x3", values, following, np.ones(len(values), dtype=bool))
    ((value, slope, keeps),) = mapped.fixed_points
    assert abs(value) < 1e-11 and keeps
    assert slope == pytest.approx(0.178, abs=1e-9)


def test_a_map_within_its_accuracy_of_the_identity_has_no_limit_cycles():
    """A cycle that retraces its path brings every start back to itself: P(v) − v is the
    integration's error, of either sign, below `SETTLED`. Its sign changes are not limit
    cycles; the map is the identity, and says so. A slowly contracting map (P' = 0.999, so
    that the samples beside v* move by 1e-6 and 5e-5) keeps its fixed point."""
    values = np.linspace(0.2, 0.8, 13)
    noise = 4e-7 * np.sin(37 * values)  # changes sign four times
    retraced = ReturnMap("x3", values, values + noise, np.ones(13, dtype=bool))
    assert np.count_nonzero(np.diff(np.sign(noise))) >= 3
    assert retraced.fixed_points == [] and retraced.identity
    assert fixed_point_words(retraced, "m").startswith("every start comes back to itself")
    slow = ReturnMap("x3", values, 0.501 + 0.999 * (values - 0.501), np.ones(13, dtype=bool))
    ((value, slope, _),) = slow.fixed_points
    assert value == pytest.approx(0.501, abs=1e-9) and slope == pytest.approx(0.999, abs=1e-9)
    assert not slow.identity


def test_the_return_map_follows_the_branch_the_free_cycles_run_on(slewing_study):
    """The study's return map lies on the branch the free cycles settle on (its values are the
    motions from that elbow's closed-form starts) and its one fixed point is their limit, the
    slope their contraction: the settling verdict names it. Mapped on the branch found at
    mid-stroke, the other elbow's, the stable fixed point was 1.377 rad, which the cycles never
    near."""
    study = slewing_study
    robot, cycle = study.robot, study.cycle
    free = study.repetitions["free"]
    held = free.held_values[:, 0]
    start, end = free.motions[0].q[0, 0], free.motions[-1].q[0, -1]
    assert robot.same_pose(start, start_configuration(held[0], 1, cycle.start), 1e-6)
    assert robot.same_pose(end, start_configuration(held[-1], -1, cycle.start), 1e-6)
    for elbow, mapped in (
        (-1, study.map),
        (1, return_map(robot, cycle, VELOCITY.resolver, values=study.map.values)),
    ):
        starts = np.array([start_configuration(v, elbow, cycle.start) for v in mapped.values])
        direct = simulate_path(robot, VELOCITY.resolver, cycle, starts, sparse=True, gain=TASK_GAIN)
        # two adaptive integrations of one motion agree within their error allowance (each lay
        # about 1.1e-6 from one at 1e-10, so 1e-6 held by chance); the elbows' maps differ by far
        # more (the other's fixed point is 1.377 rad)
        np.testing.assert_allclose(mapped.following, direct.x[:, -1, 2], atol=direct.allowance)
    ((limit, slope, keeps),) = study.map.fixed_points
    contraction = np.diff(held)[-1] / np.diff(held)[-2]
    assert abs(limit) < 1e-6 and keeps and slope == pytest.approx(contraction, abs=0.01)
    settled = free.settling_with(study.fixed_points("free"))
    assert settled.settles and settled.limit == limit
    # run on as many cycles as forecast, the repetition closes in the last of them
    more = settled.cycles_to_settle
    longer = repeat(robot, cycle, VELOCITY.resolver, start, cycles=free.cycles + more)
    largest = np.abs(longer.drift).max(axis=1)
    assert largest[-2] > SETTLED >= largest[-1]


def test_a_plan_that_changes_branch_still_finds_the_periodic_optimum(slewing_study):
    """The plan's cycle ends on the other elbow, so no periodic motion lies near it (the
    optimum seeded from it found no configuration at t = 5.655 s): it is sought again from the
    free repetition's last cycle, and found. It closes in one cycle, and its peak is no higher
    than that of the free cycles' limit, a periodic motion among those it minimises over."""
    study = slewing_study
    found = r"no configuration reaches the task at t = 5\.655 s with x3 = -109\.1°"
    with pytest.raises(InvalidInputError, match=found):
        periodic_optimum(study.robot, study.cycle, study.plan.motion, VELOCITY)
    assert "periodic" not in study.failures and study.periodic is not None
    periodic = study.repetitions["periodic"]
    assert periodic.settling.settled_at == 1
    limit = study.repetitions["free"].motions[-1].score(VELOCITY)[0]
    assert study.periodic.peak <= limit * (1 + 1e-6)


def test_the_periodic_plan_is_solved_afresh_from_the_solution_s_own_states():
    """A planar arm of three cylinders, there and back along a line at least kinetic energy:
    the solver's last trial reached no node of the final grid, so the plan's configurations,
    continued from the last states that reached them all (an earlier iterate's), missed one
    ("no configuration reaches the task at t = 0.104 s with c3 = 248.3 mm", where one does).
    They are continued from the solution's own: the plan puts the tool on the path at every
    node, closes on itself and keeps the strokes."""
    robot = load_robot(ARM3 / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    plan = plan_cycle(robot, cycle, ENERGY)
    periodic = periodic_optimum(robot, cycle, plan.motion, ENERGY, grids=(24, 48))
    space = evaluate(robot, periodic.q)
    targets = cycle.position(periodic.t)
    assert np.abs(space.y - targets).max() < 1e-9
    np.testing.assert_allclose(space.x[:, 2], periodic.r, atol=1e-9)  # c3, as the plan holds it
    np.testing.assert_allclose(periodic.q[0], periodic.q[-1], atol=1e-9)
    assert Limits.strokes(robot).margin(space.x).min() > 0


def test_without_the_free_strategy_the_branch_is_that_of_the_free_cycles_all_the_same():
    """The periodic strategy alone on the slewing arm: the free cycles, not asked for, are run
    where the optimum needs where they settle, and the return map follows their branch too
    (it found no periodic motion and mapped the other elbow, stable at 78.9°)."""
    robot = load_robot(SLEWING / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    study = run_cycle(robot, cycle, VELOCITY, cycles=6, strategy="periodic")
    assert not study.failures and study.periodic is not None
    assert set(study.repetitions) == {"periodic"}
    ((limit, slope, _),) = study.map.fixed_points
    assert abs(limit) < 1e-6 and 0 < slope < 0.2


def test_the_free_cycle_settles_only_towards_the_return_maps_stable_fixed_point(crane_study):
    """Three cycles of the crane's free law head for the return map's stable fixed point: the
    verdict names that point, not a value extrapolated from the drifts. Without the map's
    fixed points the same three cycles are no verdict of settling."""
    free = crane_study.repetitions["free"]
    ((value, _, _),) = crane_study.map.fixed_points
    report = crane_study.report()["strategies"]["free"]["repetition"]
    assert report["settles"] and report["limit_cycle_value"] == value
    words = f"converging to the return map's stable limit cycle at {1000 * value:.4g} mm"
    assert report["settling"].startswith(words)
    assert words in cycle_table(crane_study)
    assert free.settling_with(crane_study.map.fixed_points).cycles_to_settle > 1
    alone = repetition_report(free)
    assert not alone["settles"] and alone["limit_cycle_value"] is None
    assert alone["settling"].startswith("not settling after 3 cycles")
    assert crane_study.report()["strategies"]["free"]["name"] == "free, whole-cycle improved start"


def test_a_stroke_passed_on_a_later_cycle_is_reported(circle, arm_runs):
    _, _, free, _, _ = arm_runs
    first = free.first_violation
    if first is not None:  # the free arm wanders; where it passes a stroke, the cycle is named
        number, what = first
        assert 1 <= number <= 20 and "past its" in what
        assert not free.within[number - 1] and free.within[: number - 1].all()


def test_a_cycle_with_a_gap_is_refused(crane, paper_cycle):
    broken = replace(
        paper_cycle,
        segments=(
            paper_cycle.segments[0],
            Segment("2-9", np.array([1.0, -0.5]), np.array([2.0, 2.0]), 0.5),
            paper_cycle.segments[2],
        ),
    )
    with pytest.raises(InvalidInputError, match="segment 3-1 starts at"):
        plan_cycle(crane, broken)
    open_cycle = replace(paper_cycle, segments=paper_cycle.segments[:2])
    with pytest.raises(InvalidInputError, match="does not return to its start"):
        repeat(crane, open_cycle, VELOCITY.resolver, np.zeros(3), 2)


def test_the_periodic_transcription_ties_the_cycles_ends(crane, paper_cycle):
    chain = paper_cycle.chain()
    assert node_intervals(chain, 16) == [4, 6, 6]
    problem = Transcription(
        crane,
        VELOCITY,
        chain,
        2,
        Limits.strokes(crane, ["x1", "x2"]),
        16,
        np.zeros((19, 3)),
        periodic=True,
        differences=differentiation,
    )
    assert problem.D.shape == (19, 16)
    assert problem.owner[0] == problem.owner[-1] == 0
    assert problem.owner[4] == problem.owner[5] == 4  # a corner: one unknown, two nodes
    np.testing.assert_allclose(problem.D @ np.ones(16), 0.0, atol=1e-12)  # constants: no rate
    linear = problem.unknown_times()
    rates = problem.D @ linear
    np.testing.assert_allclose(rates[:-2], 1.0)  # exact for linear histories but at the wrap


def test_the_cycle_command_writes_its_report_figures_and_playback(tmp_path):
    out = tmp_path / "out"
    run = run_cli(
        "cycle",
        "--robot",
        str(ARM / "robot.toml"),
        "--cycles",
        "2",
        "--out",
        str(out),
        "--quiet",
    )
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["robot"] == "planar4r" and report["cycles"] == 2
    assert report["segments"][0]["path"] == "arc"
    assert set(report["strategies"]) == {"free", "periodic"}
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert names == [
        "cycle_drift.png",
        "cycle_return_map.png",
        "cycle_strokes.png",
        "index.html",
        "motion_cycle_free.csv",
        "motion_cycle_periodic.csv",
        "playback_cycle_free.html",
        "playback_cycle_periodic.html",
        "report.json",
    ]
    page = (out / "playback_cycle_free.html").read_text()
    assert "planar4r: cycle" in page
    assert "work cycle" in run.stdout and "drift/cycle" in run.stdout
    actuators = load_robot(ARM / "robot.toml").actuators
    for strategy in report["strategies"].values():  # the table's tool drift is the page's
        last = amount(strategy["repetition"]["tool_drift_per_cycle"][-1], "m")
        (row,) = [line for line in run.stdout.splitlines() if line.startswith(strategy["name"])]
        assert f"  {last}  " in row, (row, last)
        drifts = strategy["repetition"]["drift_per_cycle"]  # the first cycle's largest, named
        name = max(drifts, key=lambda a: abs(drifts[a][0]))
        first = f"{amount(abs(drifts[name][0]), actuators[name].unit)} {name}"
        assert f"  {first}  " in row, (row, first)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--cycles", "-1"], "--cycles: '-1' must be a whole number within [1, 10,000]"),
        (["--cycles", "0"], "--cycles: '0' must be a whole number within [1, 10,000]"),
        (["--strategy", "wander"], "invalid choice: 'wander'"),
        (["--gap-speed", "0"], "--gap-speed: '0' must be a speed within [0.001, 10]"),
        (["--gap-speed", "1e-12"], "--gap-speed: '1e-12' must be a speed within [0.001, 10]"),
    ],
)
def test_bad_cycle_options_exit_with_one_line(tmp_path, args, message):
    run = run_cli("cycle", "--out", str(tmp_path / "out"), "--quiet", *args)
    assert run.returncode == 2
    errors = [line for line in run.stderr.splitlines() if "redundancy: note:" not in line]
    assert len(errors) == 1 and message in errors[0], run.stderr


@pytest.mark.parametrize("whole", [False, True], ids=["segment", "cycle"])
def test_the_search_and_the_bound_run_one_code_on_a_segment_and_on_a_cycle(
    crane, paper_cycle, whole
):
    """A cycle is a path like any other: the fast search and the bound take the paper's
    segment 1-2 and the whole cycle's chain through the same functions, and hold the same
    properties on both (the motion spans the path, keeps every stroke and peaks where the
    search said; the bound tracks the task, keeps the strokes and is never above the search)."""
    path = paper_cycle.chain() if whole else paper_cycle["1-2"]
    search = improved_start(crane, path, VELOCITY, "x3")
    motion = search.motion()
    assert motion.segment is path and motion.t[0, -1] == pytest.approx(path.duration)
    assert motion.within_limits[0] and not motion.violations(0)
    assert motion.score(VELOCITY)[0] == pytest.approx(search.best.peak, rel=1e-3)
    optimum = global_optimum(crane, path, VELOCITY, "x3", grids=(48,), search=search)
    assert optimum.motion.max_tracking_error[0] < 1e-9
    assert optimum.motion.within_limits[0]
    assert optimum.bound <= search.best_peak * (1 + 1e-6)


def test_the_periodic_transcription_is_one_code_on_a_segment_and_on_a_cycle(circle):
    """The arm's closed circle as its one segment and as its cycle's chain: the same nodes,
    the same unknowns tied end to end, the same rates."""
    robot, cycle = circle
    problems = [
        Transcription(
            robot,
            VELOCITY,
            path,
            0,
            Limits.strokes(robot, ["x2", "x3", "x4"]),
            24,
            np.zeros((25, 4)),
            periodic=True,
        )
        for path in (cycle.segments[0], cycle.chain())
    ]
    for name in ("t", "owner", "D", "points", "y_dot"):
        np.testing.assert_array_equal(*(getattr(p, name) for p in problems))
    assert problems[0].owner[-1] == 0 and problems[0].D.shape == (25, 24)


@pytest.fixture(scope="module")
def lowered_circuit(crane, paper_cycle, tmp_path_factory):
    """The crane's cycle, one repetition, on its circuit with the relief lowered to 60 bar (a
    load-sensing pump then serves 40 bar, below the lift's and the fold's 45 bar; p_S 50 bar)
    and the telescope's acceleration limited to 0.2 m/s² (the free cycle starts it at 0.28)."""
    text = (crane.urdf.parent / "robot.toml").read_text()
    table = text[text.index("[hydraulics]") :]
    table = table.replace("relief = 210.0", "relief = 60.0")
    table = table.replace("cp_pressure = 180.0", "cp_pressure = 50.0")
    telescope = table.index("[hydraulics.cylinders.x3]")
    table = table[:telescope] + table[telescope:].replace(
        "max_acceleration = 1.0", "max_acceleration = 0.2"
    )
    path = tmp_path_factory.mktemp("circuit") / "lowered.toml"
    path.write_text(table)
    robot = load_robot("hiab031", hydraulics=path)
    return run_cycle(robot, paper_cycle, VELOCITY, cycles=1)


def _load_pressures(motion) -> np.ndarray:
    """Each cylinder's load pressure p_L (T, c) in Pa along the first motion, by the meter-in
    model from its own samples of ẋ and F_H: extending, (F + p_T A_B) / A_A; retracting,
    (−F + p_T A_A) / A_B; at least p_T."""
    circuit = motion.robot.circuit()
    bore = np.array([c.bore for c in circuit.cylinders])
    rod = np.array([c.rod for c in circuit.cylinders])
    a, b, p_t = np.pi * bore**2 / 4, np.pi * (bore**2 - rod**2) / 4, circuit.tank
    v = motion.x_dot[0][:, circuit.columns]
    force = motion.forces[0][:, circuit.columns]
    load = np.where(v >= 0, (force + p_t * b) / a, (p_t * a - force) / b)
    return np.maximum(load, p_t)


def _accelerations(motion, cycle) -> np.ndarray:
    """ẍ (T, n) along the first motion: dẋ/dt by central differences of its own samples within
    each segment (a sample at a corner ends the segment before it), one-sided of second order
    at each segment's ends."""
    t, v = motion.t[0], motion.x_dot[0]
    ends = [0, *(int(np.searchsorted(t, b - 1e-9)) + 1 for b in cycle.breaks), len(t)]
    rate = np.empty_like(v)
    for a, b in itertools.pairwise(ends):
        tt, vv = t[a:b], v[a:b]
        rate[a + 1 : b - 1] = (vv[2:] - vv[:-2]) / (tt[2:] - tt[:-2])[:, None]
        rate[a] = (-3 * vv[0] + 4 * vv[1] - vv[2]) / (tt[2] - tt[0])
        rate[b - 1] = (3 * vv[-1] - 4 * vv[-2] + vv[-3]) / (tt[-1] - tt[-3])
    return rate


def _runs(t: np.ndarray, excess: np.ndarray) -> list[tuple[float, float, float]]:
    """Each run of samples with ``excess`` > 0: its first and last time and its largest excess."""
    outside = np.flatnonzero(excess > 0)
    runs = np.split(outside, np.flatnonzero(np.diff(outside) > 1) + 1) if outside.size else []
    return [(t[r[0]], t[r[-1]], excess[r].max()) for r in runs]


def test_a_cycle_strategy_past_a_load_pressure_limit_is_named_where_and_by_how_much(
    lowered_circuit,
):
    """On a circuit serving 40 bar, both strategies' cycles pass it on the lift and the fold:
    each interval is named in the violations' words (its excess in bar, its times in the
    cycle's), with the excess and times of the load pressures computed here from the motion's
    own ẋ and F_H, in the cycle study, its report, its table and its page."""
    from redundancy.viz.report import _cycle_body

    study = lowered_circuit
    circuit = study.robot.circuit()
    served = circuit.relief - circuit.load_sensing.margin
    assert served == pytest.approx(40e5)
    report = json.loads(json.dumps(study.report(), allow_nan=False))
    table, page = cycle_table(study), _cycle_body(report)
    for name in ("free", "periodic"):
        motion, found = study.firsts[name], study.costs[name].circuit_violations
        pressures = _load_pressures(motion)
        expected = sorted(
            (start, f"{cylinder} load pressure", end, excess)
            for c, cylinder in enumerate(circuit.names)
            for start, end, excess in _runs(motion.t[0], pressures[:, c] - served)
        )
        assert {limit for _, limit, *_ in expected} == {"x1 load pressure", "x2 load pressure"}
        passed = [v for v in found if v.unit == "Pa"]
        assert [(v.start, v.actuator, v.end) for v in passed] == [e[:3] for e in expected]
        for violation, (*_, excess) in zip(passed, expected):
            assert violation.bound == "upper"
            assert violation.excess == pytest.approx(excess, rel=1e-9)
        words = [str(v) for v in found]
        assert report["strategies"][name]["circuit_violations"] == words
        line = f"{study.names[name]} passes the circuit's limits in its first cycle: "
        assert line + "; ".join(words) in table.splitlines()
        assert html.escape("; ".join(words)) in page
    worst = max(study.costs["free"].circuit_violations, key=lambda v: v.excess * (v.unit == "Pa"))
    assert str(worst).startswith("x1 load pressure 5.564 bar past its upper limit over t = 8.95")


def test_a_cycle_strategy_past_an_acceleration_limit_is_named_where_and_by_how_much(
    lowered_circuit,
):
    """With the telescope's acceleration limited to 0.2 m/s², the free cycle, which starts it
    at 0.28 m/s², passes that limit over its first 0.1 s, as ẍ = dẋ/dt from its own samples
    says; the drift-free cycle, at most 0.12 m/s², keeps it."""
    study = lowered_circuit
    free = study.firsts["free"]
    x3 = study.robot.actuators.rows("x3")[0]
    x_ddot = _accelerations(free, study.cycle)[:, x3]
    expected = _runs(free.t[0], np.maximum(x_ddot - 0.2, -0.2 - x_ddot))
    assert len(expected) == 1
    passed = [v for v in study.costs["free"].circuit_violations if v.unit == "m/s²"]
    assert [(v.actuator, v.bound, v.start, v.end) for v in passed] == [
        ("x3 acceleration", "upper", *expected[0][:2])
    ]
    # a second-order difference against the study's fourth-order one: 8e-5 m/s² apart
    assert passed[0].excess == pytest.approx(expected[0][2], abs=1e-4)
    assert str(passed[0]).startswith("x3 acceleration 0.08358 m/s² past its upper limit over t")
    periodic = study.costs["periodic"].circuit_violations
    assert not [v for v in periodic if v.unit == "m/s²"]
    held = np.abs(_accelerations(study.firsts["periodic"], study.cycle)[:, x3]).max()
    assert held < 0.2


def test_a_cycle_that_keeps_every_limit_of_the_circuit_flags_none(crane_study):
    """On the crane's own circuit both strategies' cycles keep every load pressure, the pump
    flow, every speed and acceleration, by the values computed here from their own samples:
    no strategy is flagged, the report says so with an empty list, and the table and the page
    add nothing."""
    from redundancy.viz.report import _cycle_body

    circuit = crane_study.robot.circuit()
    served = circuit.relief - circuit.load_sensing.margin
    report = json.loads(json.dumps(crane_study.report(), allow_nan=False))
    for name, motion in crane_study.firsts.items():
        v = motion.x_dot[0][:, circuit.columns]
        flows = np.where(v >= 0, circuit.piston_areas * v, -circuit.rod_side_areas * v)
        accelerations = _accelerations(motion, crane_study.cycle)[:, circuit.columns]
        assert _load_pressures(motion).max() < served
        assert flows.sum(axis=1).max() < circuit.pump_flow
        assert np.all(np.abs(v) < circuit.max_speeds)
        assert np.all(np.abs(accelerations) < circuit.max_accelerations)
        assert crane_study.costs[name].circuit_violations == ()
        assert report["strategies"][name]["circuit_violations"] == []
    assert "circuit's limits" not in cycle_table(crane_study)
    assert "circuit, first cycle" not in _cycle_body(report)


def test_a_held_speed_stepped_at_a_corner_where_the_tool_rests_passes_its_acceleration(
    crane, paper_cycle
):
    """With trapezoidal profiles the tool rests at every corner, so the task asks no step of ẋ
    there; the drift-free plan, solved segment by segment, steps the telescope's speed at the
    corner 1-2 → 2-3 all the same. Across that corner ẋ changes by Δẋ between the samples on
    either side, a mean acceleration Δẋ / Δt past the telescope's 1 m/s², which the cycle study
    names at the corner's time; the free law, smooth through it, is not flagged."""
    segments = tuple(
        replace(s, profile="trapezoidal", acceleration=0.5) for s in paper_cycle.segments
    )
    cycle = replace(paper_cycle, segments=segments)
    study = run_cycle(crane, cycle, VELOCITY, cycles=1)
    corner = cycle.offsets[1]
    motion = study.firsts["periodic"]
    t, x3 = motion.t[0], motion.x_dot[0][:, crane.actuators.rows("x3")[0]]
    c = int(np.argmin(np.abs(t - corner)))
    assert t[c] == pytest.approx(corner) and abs(x3[c + 1] - x3[c]) > 0.05  # the step
    across = (x3[c + 1] - x3[c - 1]) / (t[c + 1] - t[c - 1])
    maximum = crane.circuit().max_accelerations[2]
    assert across > maximum
    at_corner = [v for v in study.costs["periodic"].circuit_violations if v.start == t[c]]
    assert [(v.actuator, v.bound, v.end) for v in at_corner if "x3" in v.actuator] == [
        ("x3 acceleration", "upper", t[c])
    ]
    found = next(v for v in at_corner if v.actuator == "x3 acceleration")
    assert found.excess == pytest.approx(across - maximum, rel=1e-12)
    assert f"x3 acceleration {across - maximum:.4g} m/s² past its upper limit" in cycle_table(study)
    assert study.costs["free"].circuit_violations == ()


def test_a_corner_turns_a_slew_whose_stroke_spans_more_than_a_turn_the_short_way(tmp_path):
    """The slewing 3R arm with its slew x1 held over [−4, 4] rad, there and back along a line:
    a start of b-a one turn below the plan's own is the same pose, and the corner from a-b's
    end goes to it the short way, as to the plan's own start, where it turned the slew a whole
    turn round and lost the task point on the way."""
    shutil.copy(SLEWING / "arm.urdf", tmp_path)
    toml = (SLEWING / "slew_held.toml").read_text()
    toml = toml.replace("stroke = [-3.14159, 3.14159]", "stroke = [-4.0, 4.0]")
    (tmp_path / "robot.toml").write_text(toml.replace('task = "line.toml"', 'task = "c.toml"'))
    line = (SLEWING / "line.toml").read_text()
    (tmp_path / "c.toml").write_text(line.replace('["a-b"]', '["a-b", "b-a"]'))
    robot = load_robot(tmp_path / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    plan = plan_cycle(robot, cycle, VELOCITY)
    there, back = plan.segment_motions
    lower = back.q[0, 0].copy()
    lower[0] -= 2 * np.pi
    assert lower[0] >= -4.0 and robot.same_pose(lower, back.q[0, 0], 1e-12)
    turned = simulate(robot, VELOCITY.resolver, cycle["b-a"], lower[None])
    corners = [
        _corner(
            robot,
            cycle["a-b"],
            there,
            cycle["b-a"],
            start,
            ("x1",),
            gap_speed(robot, ("x1",)),
            None,
        )
        for start in (back, turned)
    ]
    for corner in corners:
        assert corner.within_limits and corner.reason is None, corner.reason
        assert abs(corner.held_delta[0]) < np.pi  # the short way round
    assert corners[1].held_delta == pytest.approx(corners[0].held_delta, abs=1e-12)
    np.testing.assert_allclose(corners[1].path, corners[0].path, atol=1e-12)


def test_an_integral_objective_runs_the_free_strategy_alone_and_says_why(crane, paper_cycle):
    """The drift-free plan minimises a peak: asked for by name with the LS pump energy, an
    integral, it is refused before any work; with both strategies, the free one runs and the
    cycle study says why the periodic one does not."""
    from redundancy import LS_ENERGY

    with pytest.raises(InvalidInputError, match=r"periodic strategy minimises a peak.*'integral'"):
        run_cycle(crane, paper_cycle, LS_ENERGY, cycles=1, strategy="periodic")
    study = run_cycle(crane, paper_cycle, LS_ENERGY, cycles=1)
    assert set(study.repetitions) == {"free"}
    assert study.failures["periodic"].endswith("only the free strategy runs")
    alone = run_cycle(crane, paper_cycle, LS_ENERGY, cycles=1, strategy="free")
    assert set(alone.repetitions) == {"free"} and "periodic" not in alone.failures


def test_a_cycle_whose_actuators_all_stayed_put_names_none_of_them(crane_study):
    """The drift-free plan closes every cycle: where no actuator moved in a cycle, to the
    integration's rounding, the table's largest drift is 0, naming no actuator, where it named
    whichever came first (a drift of 2e-16 m read "0 mm x2")."""
    periodic = crane_study.repetitions["periodic"]
    (row,) = [r for r in cycle_table(crane_study).splitlines() if r.startswith("periodic")]
    cells = [cell for cell in row.split("  ") if cell.strip()]
    last = np.abs(periodic.drift[-1]).max()
    assert (cells[3].strip() == "0") == (last < ROUNDING)
    named = any(name in cells[3] for name in crane_study.robot.actuators.names)
    assert named == (last >= ROUNDING)
