"""The improved searches: the fast search against the paper's uniform sweep, both through the
one evaluation; adaptive integration against the fixed-step reference; a user's own actuator
kind and objective through every search. The sweeps here are coarser than the benchmark's (23
samples, refined locally at the 1,000-sample spacing where the best start lies) to keep the tests
quick."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from declarations import write_transmissions
from slewing3r_closed_form import (
    shoulder_held_configuration,
    slew_held_configuration,
    start_configuration,
)

import redundancy.planning.integrate as integrate
from redundancy import (
    ActuatorMap,
    InvalidInputError,
    Objective,
    UnreachableError,
    actuator_space,
    default_start,
    global_optimum,
    improved_start,
    load_robot,
)
from redundancy.model.loading import bundled_root
from redundancy.model.parameters import Number
from redundancy.model.values import modulo_turn
from redundancy.planning import starts
from redundancy.planning.brackets import (
    edge_probes,
    end_probe,
    grid_over,
    interpolant_zeros,
    summit_probes,
    vertex_probes,
)
from redundancy.planning.cycles import improved_cycle_start
from redundancy.planning.ik import fold_side, inverse_kinematics
from redundancy.planning.integrate import simulate, stroke_extremes
from redundancy.planning.starts import evaluate_starts
from redundancy.planning.tasks import Segment, WorkCycle
from redundancy.resolution.laws import GradientProjection, MinVelocityNorm
from redundancy.resolution.objectives import ENERGY, VELOCITY
from redundancy.resolution.state import evaluate
from redundancy.study.cycles import best_report

SEGMENTS = ["1-2", "2-3", "3-1"]
SLEWING = Path(__file__).parent / "data" / "slewing3r"
COARSE = 23  # samples of the test's uniform sweep
DENSE = 1000  # the benchmark's reference sweep, whose spacing the local refinement uses


@pytest.fixture(scope="module")
def cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


@pytest.fixture(scope="module")
def searches(crane, cycle):
    return {name: improved_start(crane, cycle[name], VELOCITY) for name in SEGMENTS}


def test_hermite_extremes_find_a_maximum_between_samples():
    """x = sin t sampled at 0, 1, 2 s: the maximum 1 at t = π/2 lies between samples."""
    t = np.array([[0.0, 1.0, 2.0]])
    x = np.sin(t)[..., None]
    lowest, highest = stroke_extremes(t, x, np.cos(t)[..., None])
    assert highest[0, 0] == pytest.approx(1.0, abs=5e-3) and highest[0, 0] > np.sin(2.0)
    assert lowest[0, 0] == pytest.approx(np.sin(1.0))  # the start itself is excluded


def test_hermite_extremes_bound_the_interpolant_sampled_densely():
    """Random samples, some motions padded by repeating their last sample (h = 0): with the start
    (which they leave out) the extremes are those of the samples and of the cubic Hermite
    interpolant between them, p(s) = h₀₀ x₀ + h₁₀ h ẋ₀ + h₀₁ x₁ + h₁₁ h ẋ₁, evaluated at 4,001
    points of each interval (its extremum between two of them is within the spacing² of theirs);
    a NaN sample is kept."""
    rng = np.random.default_rng(3)
    s = np.linspace(0.0, 1.0, 4001)
    basis = np.stack(
        [1 - 3 * s**2 + 2 * s**3, s - 2 * s**2 + s**3, 3 * s**2 - 2 * s**3, s**3 - s**2]
    )
    for trial in range(300):
        k, T, n = rng.integers(1, 4), rng.integers(2, 7), rng.integers(1, 4)
        t = np.cumsum(rng.uniform(0.05, 1.0, (k, T)), axis=1)
        x, x_dot = rng.normal(size=(k, T, n)), rng.normal(scale=3.0, size=(k, T, n))
        if trial % 3 == 0:  # padded: the last sample repeated
            t[:, -1], x[:, -1], x_dot[:, -1] = t[:, -2], x[:, -2], x_dot[:, -2]
        lowest, highest = stroke_extremes(t, x, x_dot)
        lowest, highest = np.minimum(lowest, x[:, 0]), np.maximum(highest, x[:, 0])
        h = np.diff(t, axis=1)[..., None]
        pieces = [x[:, :-1], h * x_dot[:, :-1], x[:, 1:], h * x_dot[:, 1:]]
        dense = np.einsum("cs,ckun->kuns", basis, np.stack(pieces))  # (k, T − 1, n, s)
        dense_low, dense_high = dense.min(axis=(1, 3)), dense.max(axis=(1, 3))
        scale = 1e-6 * (1 + sum(np.abs(piece).max() for piece in pieces))
        assert np.all(lowest <= dense_low + 1e-12) and np.all(lowest >= dense_low - scale)
        assert np.all(highest >= dense_high - 1e-12) and np.all(highest <= dense_high + scale)
    x[0, -1, 0] = np.nan
    lowest, highest = stroke_extremes(t, x, x_dot)
    assert np.isnan(lowest[0, 0]) and np.isnan(highest[0, 0])
    lowest, highest = stroke_extremes(t[:, :1], x[:, :1], x_dot[:, :1])  # the start alone
    assert np.all(lowest == np.inf) and np.all(highest == -np.inf)
    with pytest.raises(ValueError, match="T ≥ 1"):
        stroke_extremes(t[:, :0], x[:, :0], x_dot[:, :0])
    with pytest.raises(ValueError, match=r"x_dot \(k, T, n\)"):
        stroke_extremes(t, x, x_dot[..., :1])


def test_the_zeros_of_the_interpolant_through_the_probes_are_the_polynomials_zeros():
    """Lines and parabolas through two or three random points: each zero found makes the
    Lagrange interpolant vanish, and they are the real zeros numpy finds from its fitted
    coefficients; and the degenerate parabolas: through collinear points, a double zero, none."""
    rng = np.random.default_rng(7)
    for u, m in (rng.normal(size=(2, count)) for count in (2, 3) for _ in range(200)):
        u.sort()
        zeros = interpolant_zeros(u.tolist(), m.tolist())

        def terms(z, u=u, m=m):  # m_i L_i(z), whose sum is the interpolant
            others = [np.delete(u, i) for i in range(len(u))]
            return np.array([m[i] * np.prod((z - o) / (u[i] - o)) for i, o in enumerate(others)])

        assert all(abs(terms(z).sum()) <= 1e-12 * np.abs(terms(z)).sum() for z in zeros)
        roots = np.roots(np.polyfit(u, m, len(u) - 1))
        real = np.sort(roots[roots.imag == 0].real)
        assert np.allclose(np.sort(zeros), real, rtol=1e-9, atol=1e-12)
    assert interpolant_zeros([0.0, 1.0, 2.0], [1.0, 0.0, -1.0]) == [1.0]  # collinear
    assert interpolant_zeros([-1.0, 0.0, 1.0], [1.0, 0.0, 1.0]) == [0.0]  # u²
    assert interpolant_zeros([-1.0, 0.0, 1.0], [2.0, 1.0, 2.0]) == []  # u² + 1


@pytest.mark.parametrize("sparse", [True, False], ids=["steps", "grid"])
def test_adaptive_motions_agree_with_the_fixed_step_method_within_the_error_allowance(
    crane, cycle, sparse
):
    segment = cycle["3-1"]
    ik = inverse_kinematics(crane, segment.start, ["x3"], np.array([[0.6], [0.75], [0.9]]))
    reference = simulate(crane, VELOCITY.resolver, segment, ik.q, 0.005, method="rk4")
    motion = simulate(crane, VELOCITY.resolver, segment, ik.q, sparse=sparse)
    lowest, highest = stroke_extremes(motion.t, motion.x, motion.x_dot)
    lowest, highest = np.minimum(lowest, motion.x[:, 0]), np.maximum(highest, motion.x[:, 0])
    allowance = integrate.ALLOWANCE * integrate.TOLERANCE
    assert np.abs(lowest - reference.x.min(axis=1)).max() < allowance
    assert np.abs(highest - reference.x.max(axis=1)).max() < allowance
    np.testing.assert_allclose(motion.x[:, -1], reference.x[:, -1], atol=allowance)
    np.testing.assert_allclose(motion.peak_velocity_norm, reference.peak_velocity_norm, rtol=1e-3)
    assert motion.max_tracking_error.max() < allowance


def test_dense_output_lies_on_the_grid_and_matches_the_law(crane, cycle):
    """Grid samples come from the dense output: on the uniform grid, and their ẋ is the law's
    at the sampled configuration (J_H ẋ = ẏ_d, Eq. 16)."""
    segment = cycle["1-2"]
    start = inverse_kinematics(crane, segment.start, ["x3"], np.array([[1.0]])).q
    motion = simulate(crane, VELOCITY.resolver, segment, start, 0.05)
    np.testing.assert_allclose(motion.t[0], np.linspace(0, segment.duration, 101))
    J_H = actuator_space(crane, motion.q[0]).J_H
    np.testing.assert_allclose(
        np.einsum("kij,kj->ki", J_H, motion.x_dot[0]),
        np.broadcast_to(segment.velocity, (101, 2)),
        atol=1e-12,
    )


def test_sparse_motions_on_the_grid_are_the_motions_integrated_on_the_grid(crane, cycle):
    """A batch integrated sparsely, then sampled on the grid from its steps, equals the batch
    integrated on the grid (same steps, same dense output), every motion of it and each one
    selected alone; with closed-loop tracking too, whose law the steps carry: at every sample
    J_H ẋ = ẏ_d + K (y_d − y) (Eq. 16), and q follows the fixed-step method."""
    segment = cycle["3-1"]
    values = np.array([[0.3], [0.6], [0.75], [0.9]])
    starts = inverse_kinematics(crane, segment.start, ["x3"], values).q
    for gain in (0.0, 20.0):
        sparse = simulate(crane, VELOCITY.resolver, segment, starts, gain=gain, sparse=True)
        grid = simulate(crane, VELOCITY.resolver, segment, starts, 0.02, gain=gain)
        assert sparse.t.shape[1] != grid.t.shape[1]
        for rows in (slice(None), [2], [3, 0]):
            again = (sparse if rows == slice(None) else sparse.select(rows)).on_grid(0.02)
            assert not again.sparse and again.allowance == 0.0
            for name in ("t", "q", "x", "x_dot", "y"):
                np.testing.assert_allclose(
                    getattr(again, name), getattr(grid, name)[rows], rtol=0, atol=1e-12
                )
            np.testing.assert_array_equal(again.within_limits, grid.within_limits[rows])
        t, (count, T, n) = grid.t[0], grid.q.shape
        space = actuator_space(crane, grid.q.reshape(count * T, n))
        wanted = segment.velocity_at(t) + gain * (segment.position(t) - grid.y)
        np.testing.assert_allclose(
            np.einsum("kij,kj->ki", space.J_H, grid.x_dot.reshape(count * T, n)),
            wanted.reshape(count * T, -1),
            atol=1e-12,
        )
        reference = simulate(crane, VELOCITY.resolver, segment, starts, 0.02, gain, method="rk4")
        allowance = integrate.ALLOWANCE * integrate.TOLERANCE
        np.testing.assert_allclose(grid.q, reference.q, rtol=0, atol=allowance)
    with pytest.raises(InvalidInputError, match="adaptively integrated"):
        simulate(crane, VELOCITY.resolver, segment, starts, method="rk4").on_grid()


@pytest.mark.parametrize("name", SEGMENTS)
def test_fast_search_and_uniform_sweep_agree(crane, cycle, searches, name):
    """Same feasible range within one sample spacing; same best peak within 0.5% of the best a
    1,000-sample sweep finds (the sweep's peak falls over its feasible range, so that best lies
    within one coarse spacing above the coarse sweep's best, where the 1,000-sample grid is
    swept)."""
    segment, fast = cycle[name], searches[name]
    assert fast.method == "fast"
    sweep = improved_start(crane, segment, VELOCITY, "x3", COARSE, method="sweep")
    spacing = 1.09 / (COARSE - 1)
    assert np.abs(np.subtract(fast.feasible_range, sweep.feasible_range)).max() <= spacing
    peaks = [s.peak for s in sweep.feasible]
    assert np.all(np.diff(peaks) < 0) and sweep.best == sweep.feasible[-1]
    grid = np.linspace(0.0, 1.09, DENSE)
    local = grid[(grid >= sweep.best.value) & (grid <= sweep.best.value + spacing)]
    dense = evaluate_starts(crane, segment, VELOCITY, "x3", local).best
    assert abs(fast.best.peak - dense.peak) / dense.peak < 0.005
    assert fast.best.value >= dense.value - 1.09 / (DENSE - 1)


@pytest.mark.parametrize("name", SEGMENTS)
def test_fast_searchs_best_start_keeps_every_stroke_on_the_grid(searches, name):
    motion = searches[name].motion()
    assert motion.within_limits[0], motion.violations(0)
    assert VELOCITY.reduce(motion.t, motion.values(VELOCITY))[0] == pytest.approx(
        searches[name].best.peak, rel=1e-3
    )


def test_a_feasible_set_narrower_than_the_first_grid_is_found(crane):
    """Along y2 = −0.5 m out to 10 mm short of the crane's farthest reach (3.823 m), the starts
    that keep every stroke span about 11 mm of x3, less than the first grid's spacing: none of
    the grid's 12 is feasible, and all stop early. The margin's summit is climbed to a feasible
    start, and its ends are located as a 400-sample sweep locates them, within its spacing."""
    edge = Segment("edge", np.array([3.5, -0.5]), np.array([3.813423, -0.5]), 0.5)
    fast = improved_start(crane, edge, VELOCITY, "x3")
    assert not any(s.feasible for s in fast.samples[: starts.GRID])
    sweep = improved_start(crane, edge, VELOCITY, "x3", 400, method="sweep")
    lower, upper = sweep.feasible_range
    assert upper - lower < 0.02
    spacing = 1.09 / 399
    assert np.abs(np.subtract(fast.feasible_range, sweep.feasible_range)).max() <= spacing
    assert fast.best.peak <= sweep.best.peak


def test_summit_probes_halve_the_intervals_beside_the_highest_margin():
    """Around the highest margin (−1 at 2), where twice the steepest slope seen (1 per unit,
    from 2 to 3) lifts it above 0 within a neighbour's distance; not where it cannot."""
    values, margins = np.array([0.0, 1.0, 2.0, 3.0]), np.array([-3.0, -np.inf, -1.0, -2.0])
    assert summit_probes(values, margins, 0.1) == [1.5, 2.5]
    assert summit_probes(values, margins, 1.0) == []
    assert summit_probes(values, np.full(4, -np.inf), 0.1) == []
    assert summit_probes(values, margins - 2.5, 0.1) == []  # −3.5 + 2 × 1 × 1 < 0


def test_edge_probes_divide_the_intervals_beside_a_branchs_end_where_its_margin_is_below_0():
    """The branch has no configuration at 0 and 5 (margin −inf); beside 0 the margin is −1,
    beside 5 −2: each interval is divided into five, until it is within the tolerance,
    whether the margin rises towards the end (at 1) or falls (at 4). Not where the margin
    beside the end is ≥ 0: the reachable brackets locate that end."""
    values = np.arange(6.0)
    margins = np.array([-np.inf, -1.0, -2.0, -1.0, -2.0, -np.inf])
    fifths = [0.2, 0.4, 0.6, 0.8]
    assert edge_probes(values, margins, 0.1) == pytest.approx(fifths + [4 + f for f in fifths])
    assert edge_probes(values, margins, 1.0) == []
    assert edge_probes(values, np.where(values == 1, 0.5, margins), 0.1) == pytest.approx(
        [4 + f for f in fifths]
    )


def test_the_grid_over_pieces_lies_along_them_with_their_ends_and_one_in_each_gap():
    """Three values along [0, 1], [3.5, 3.7] and [9, 10] laid end to end (2.2 long): 0, 3.6
    (1.1 along) and 10, every piece's ends, and the middle of each gap. Four along [0, 1],
    [3.5, 3.52] and [9, 10] (2.02 long, every 0.673): 0, 0.673, 9.327 and 10, the ends, the
    gaps' middles, and 3.51, the middle of the piece they step over. Twelve along [−2, 0.7]:
    twelve, the last the piece's end exactly (along it, −2 + 2.7 is 2e-16 past it)."""
    pieces = np.array([[0.0, 1.0], [3.5, 3.7], [9.0, 10.0]])
    expected = [0.0, 1.0, 2.25, 3.5, 3.6, 3.7, 6.35, 9.0, 10.0]
    np.testing.assert_allclose(grid_over(pieces, 3), expected)
    pieces[1, 1] = 3.52
    step = 2.02 / 3
    expected = [0.0, step, 1.0, 2.25, 3.5, 3.51, 3.52, 6.26, 9.0, 9 + 2 * step - 1.02, 10.0]
    np.testing.assert_allclose(grid_over(pieces, 4), expected)
    grid = grid_over(np.array([[-2.0, 0.7]]), 12)
    assert len(grid) == 12 and grid[-1] == 0.7


def test_a_piece_of_a_branch_at_its_end_narrower_than_the_reach_scan_is_searched():
    """The slewing arm near its base, x3 held: on the elbow q1 − atan2(y, x) < 0, the start is
    reached inside the joint limits (|q2| ≤ 2.8) for x3 in [−0.04, 2.51] and, cut off from
    that, in [−2.508, −2.38]: a piece 0.13 rad wide at the end of the branch (its fold, past
    which no configuration of it reaches the start), which the reach scan's values, 0.24 rad
    apart, step over. The least peak over both elbows, by brute force over x3 in steps of 2
    mrad from the closed form, lies on it, at its feasible end (0.0859 rad²/s² at x3 =
    −2.384), beside which the peak changes by 0.019 rad²/s² per rad (for 7 mrad, then ten
    times faster past a kink): the fast search, locating that end to within 2.8 mrad (0.06 %
    of the peak there), is within 0.1 %. It found 0.0955, 11 % above, elsewhere, before the
    scan searched beside a branch's end (`edge_probes`)."""
    robot = load_robot(SLEWING / "robot.toml")
    line = Segment("near the base", np.array([0.453, 0.223]), np.array([0.44, -0.292]), 0.2)
    values = np.linspace(-2.8, 2.8, 2801)
    least = {}
    for elbow in (1, -1):
        found = [start_configuration(v, elbow, line.start) for v in values]
        q = np.array([each for each in found if each is not None and abs(each[1]) <= 2.8])
        motions = simulate(robot, VELOCITY.resolver, line, q)
        peaks = np.where(motions.within_limits, motions.score(VELOCITY), np.inf)
        least[elbow] = (peaks.min(), q[np.argmin(peaks)])
    peak, start = least[-1]
    assert peak < 0.95 * least[1][0] and -2.51 < start[2] < -2.38
    search = improved_start(robot, line, VELOCITY, "x3")
    assert search.best_peak <= 1.001 * peak
    assert robot.same_pose(search.motion().q[0, 0], start, 0.02)


def test_vertex_probes_search_a_second_basin_whose_parabola_dips_below_the_least_peak():
    """The least peak is 1.0 at 1: the parabola's vertex 5/6. The local minimum 1.1 at 4, with
    1.3 at 5, dips to 1.1 − 1.35² / (4 · 1.55) = 0.806 < 1.0 at 4 + 1.35 / 3.1: probed too.
    With 2.9 at 5 it dips to 1.068 only: not probed."""
    values = np.arange(7.0)
    peaks = np.array([2.0, 1.0, 3.0, 4.0, 1.1, 1.3, 2.0])
    assert vertex_probes(values, peaks, 0.01) == pytest.approx([5 / 6, 4 + 1.35 / 3.1])
    assert vertex_probes(values, np.where(values == 5, 2.9, peaks), 0.01) == pytest.approx([5 / 6])


def test_the_fast_search_finds_the_least_peak_far_from_the_first_grids_least_sample():
    """The slewing arm along a line with its shoulder x2 held: the least peak of all is
    0.03278 rad²/s² at x2 = −1.228, on the closed form's elbow +1 (the wrist anticlockwise of
    the line from the base to the start), by brute force over x2 in steps of 2 mrad from the
    closed form, both elbows. The fast search found 0.0371, 13 % above, at x2 = −2.511 on the
    other elbow: its first grid, spread over the gaps between the reachable pieces, sampled
    that basin above the other's least sample, and only the least sample's basin was refined.
    With the grid along the pieces and the vertex probes in every basin whose parabola dips
    below the least sample, it is within 0.5 %: the peak rises about 0.17 % per mrad beside
    that kinked minimum, and the search locates it to 2.8 mrad."""
    robot = load_robot(SLEWING / "robot.toml")
    start, end = [0.6152931413917564, 0.899375434874695], [-0.1869542865721412, 1.21884518117754]
    line = Segment("line", np.array(start), np.array(end), 0.2)
    least = {}
    for elbow in (1, -1):
        found = [
            shoulder_held_configuration(v, elbow, line.start) for v in np.linspace(-2.8, 2.8, 2801)
        ]
        q = np.array([each for each in found if each is not None and abs(each[2]) <= 2.8])
        np.testing.assert_allclose(
            actuator_space(robot, q).y, np.tile(line.start, (len(q), 1)), atol=1e-12
        )
        motions = simulate(robot, VELOCITY.resolver, line, q)
        peaks = np.where(motions.within_limits, motions.score(VELOCITY), np.inf)
        least[elbow] = (peaks.min(), q[np.argmin(peaks)])
    peak, best = least[1]
    assert peak < 0.95 * least[-1][0] and best[1] == pytest.approx(-1.228)
    search = improved_start(robot, line, VELOCITY, "x2")
    assert search.best_peak <= 1.005 * peak
    assert robot.same_pose(search.motion().q[0, 0], best, 0.02)


def test_a_start_past_a_slews_stroke_end_is_taken_a_turn_back_inside_it():
    """The slewing arm with its slew's stroke one turn, [−π, π], and its shoulder x2 held: on
    the closed form's elbow −1 (the wrist clockwise of the line from the base to the start)
    the slew of the starts runs across ±π as x2 grows. Continued from a start near −π, the
    start at x2 = 0.84 had q1 = −3.23, outside the stroke; the same pose a turn on, q1 = 3.05,
    is inside it, and its motion keeps every stroke with the least peak of all: 0.01581
    rad²/s², by brute force over x2 in steps of 2 mrad from the closed form, q1 taken inside
    the stroke. The fast search found 0.0240 (0.0335 before it searched a branch's end), the
    sweep of 1,000 samples 0.0259, both elsewhere: continuation kept that slew outside the
    stroke. It now takes the turn inside a joint's range where there is one: within 0.5 %
    (the search's tolerance, 2.8 mrad)."""
    robot = load_robot(SLEWING / "slew_held.toml")
    start = np.array([-1.3948182450898194, -0.919903416871264])
    line = Segment("line", start, np.array([-1.8224244790875685, -0.13712840407334548]), 0.2)
    least = {}
    for elbow in (1, -1):
        values = np.linspace(-2.8, 2.8, 2801)
        found = [shoulder_held_configuration(v, elbow, line.start) for v in values]
        q = np.array([each for each in found if each is not None and abs(each[2]) <= 2.8])
        q[:, 0] = modulo_turn(q[:, 0])  # the slew inside its stroke
        motions = simulate(robot, VELOCITY.resolver, line, q)
        peaks = np.where(motions.within_limits, motions.score(VELOCITY), np.inf)
        least[elbow] = (peaks.min(), q[np.argmin(peaks)])
    peak, best = least[-1]
    assert peak < 0.7 * least[1][0] and best[1] == pytest.approx(0.84)
    search = improved_start(robot, line, VELOCITY, "x2")
    assert search.best_peak <= 1.005 * peak
    q = search.motion().q[0, 0]
    assert robot.same_pose(q, best, 0.02) and abs(q[0]) <= np.pi


def test_the_least_peak_is_probed_beside_a_feasible_end_and_past_a_kink():
    """End probe: the least peak (1.0 at 0) has a feasible neighbour on one side only: the
    midpoint towards it, while it is farther than a quarter of the grid's spacing. Vertex
    probe: the parabola's vertex, unless it creeps (within an eighth of the wider side from
    the least peak, as at a kink of the peak), then the golden section of that side."""
    values, peaks = np.array([-1.0, 0.0, 1.0, 2.0]), np.array([np.inf, 1.0, 3.0, 4.0])
    assert end_probe(values, peaks, 3.9) == [0.5]
    assert end_probe(values, peaks, 4.0) == []
    assert end_probe(values, np.array([5.0, 1.0, 3.0, 4.0]), 1.0) == []  # both sides: a vertex
    assert vertex_probes(np.array([0.0, 1.0, 3.0]), np.array([2.0, 1.0, 2.0]), 0.01) == [1.5]
    values = np.array([0.0, 1.0, 9.0])
    assert vertex_probes(values, np.array([2.0, 1.0, 8.0]), 0.01) == pytest.approx([2.9])
    kink = vertex_probes(values, np.array([2.0, 1.0, 20.0]), 0.01)  # the vertex: 1.83
    assert kink == pytest.approx([1.0 + 8.0 * (3 - 5**0.5) / 2])


def test_the_fast_search_finds_an_interior_least_peak_beside_a_feasible_end():
    """The continuous-joint arm's 2-1, least kinetic energy: the peak is least 0.19 rad inside
    the feasible set, next to its end, where it is 14 % lower than at the end. The search used
    to stop at the end; it is now within 0.5 % of a 200-sample sweep's best."""
    arm = load_robot(Path(__file__).parent / "data" / "unbounded")
    segment = WorkCycle.from_toml(arm.task_file, dimension=arm.m)["2-1"]
    fast = improved_start(arm, segment, ENERGY, held="x3")
    sweep = improved_start(arm, segment, ENERGY, held="x3", method="sweep", samples=200)
    lower, _ = sweep.feasible_range
    assert sweep.best.value - lower > 0.15  # inside, not at the end
    assert fast.best.peak <= 1.005 * sweep.best.peak


def test_fast_search_needs_few_simulations(searches):
    """A fraction of the paper's 100 samples; the feasible ends located to the tolerance."""
    for fast in searches.values():
        assert fast.simulations < 40 and fast.rounds <= 3


def test_a_search_keeps_its_rounds_motions_and_each_samples_start(searches):
    """Each round's motions are kept as integrated; joined, sample i's motion is row rows[i],
    and it starts at the sample's start configuration, at its held value."""
    search = searches["3-1"]
    assert search.rounds == len(search.batches) == 2
    assert len(search.trajectory) == sum(len(b) for b in search.batches) == search.simulations
    x3 = list(search.robot.actuators.names).index("x3")
    for sample, row in zip(search.samples, search.rows):
        if row < 0:
            with pytest.raises(InvalidInputError, match="unreachable"):
                search.start_configuration(sample)
            continue
        q = search.start_configuration(sample)
        np.testing.assert_array_equal(q, search.trajectory.q[row, 0])
        assert search.trajectory.x[row, 0, x3] == pytest.approx(sample.value, abs=1e-9)


def test_one_motion_signature_for_every_search(crane, cycle, searches):
    """`motion()` is the best's motion, `motion(sample)` any reachable sample's, whatever the
    method."""
    sweep = improved_start(crane, cycle["1-2"], VELOCITY, samples=5, method="sweep")
    for search in (searches["1-2"], sweep):
        best = search.motion()
        np.testing.assert_array_equal(best.q, search.motion(search.best).q)
        assert best.t.shape == (1, 501)


def test_search_rejects_bad_arguments(crane, cycle):
    segment = cycle["1-2"]
    with pytest.raises(InvalidInputError, match="x9"):
        improved_start(crane, segment, VELOCITY, held="x9")
    with pytest.raises(InvalidInputError, match="unknown actuators"):
        improved_start(crane, segment, VELOCITY, checked=("x1", "y7"))
    with pytest.raises(InvalidInputError, match="unknown method 'grid'"):
        improved_start(crane, segment, VELOCITY, method="grid")
    with pytest.raises(InvalidInputError, match="whole number"):
        improved_start(crane, segment, VELOCITY, samples=2.5)


class GearedCylinder(ActuatorMap):
    """A user's own kind, written here: the telescope through a 2:1 gear, x = 2 (q + offset).
    Only `evaluate` and `rate`: the group methods come from the base class."""

    parameters = (Number("offset", "x / 2 − q, m", 0.0),)

    def __init__(self, name, joint, lower=-np.inf, upper=np.inf, offset=0.0):
        super().__init__(name, joint, lower, upper)
        self.offset = offset

    def evaluate(self, kinematics):
        row = np.zeros_like(kinematics.q)
        row[:, self.index] = 2.0
        return 2.0 * (kinematics.q[:, self.index] + self.offset), row

    def rate(self, kinematics):
        return np.zeros_like(kinematics.q)


def test_a_users_own_actuator_kind_runs_through_every_path(tmp_path, crane, cycle):
    """The geared telescope doubles x3 and its stroke: actuator space, the fast search and the
    bound all run on it, and the best start is the crane's at twice the stroke."""
    telescope = crane.actuators["x3"]
    maps = [a for a in crane.actuators if a.name != "x3"]
    maps.append(GearedCylinder("x3", telescope.joint, 0.0, 2 * 1.09, telescope.offset))
    path = tmp_path / "geared.urdf"
    path.write_text(
        write_transmissions((bundled_root() / "hiab031" / "hiab031.urdf").read_text(), maps)
    )
    geared = load_robot(path, task_axes="xz")
    q = (crane.lower + crane.upper) / 2
    np.testing.assert_allclose(
        actuator_space(geared, q).x[0, 2], 2 * actuator_space(crane, q).x[0, 2]
    )
    segment = cycle["1-2"]
    search = improved_start(geared, segment, VELOCITY)
    assert search.best.value == pytest.approx(2 * 1.09)
    assert search.motion().within_limits[0]
    optimum = global_optimum(geared, segment, VELOCITY, grids=(12, 24))
    assert optimum.motion.within_limits[0] and optimum.bound <= search.best.peak * (1 + 1e-6)


def test_a_users_own_objective_runs_through_the_sweep_the_fast_search_and_the_bound(crane, cycle):
    """Peak telescope speed |ẋ3| with the unweighted law: every search takes it, and the bound
    is at or below the improved start's."""

    def telescope_speed(space, x_dot):
        return x_dot[:, 2] ** 2

    own = Objective("telescope", MinVelocityNorm(), telescope_speed, "ẋ3²", "m²/s²")
    segment = cycle["2-3"]
    fast = improved_start(crane, segment, own)
    sweep = improved_start(crane, segment, own, samples=12, method="sweep")
    assert fast.best is not None and sweep.best is not None
    assert fast.best.peak <= sweep.best.peak * (1 + 1e-3)
    motion = fast.motion()
    np.testing.assert_allclose(motion.values(own)[0], motion.x_dot[0, :, 2] ** 2, rtol=1e-12)
    optimum = global_optimum(crane, segment, own, grids=(12, 24), search=fast)
    assert optimum.bound <= fast.best.peak * (1 + 1e-6)
    integral = dataclasses.replace(own, reduction="integral")
    assert improved_start(crane, segment, integral).best is not None
    with pytest.raises(InvalidInputError, match="peak"):
        global_optimum(crane, segment, integral)
    with pytest.raises(InvalidInputError, match="reduction 'sum'"):
        dataclasses.replace(own, reduction="sum")


def test_gradient_projection_runs_through_the_search(crane, cycle):
    """Any law: gradient projection's own objective through the fast search."""
    law = dataclasses.replace(VELOCITY, name="projected", resolver=GradientProjection(0.1))
    assert improved_start(crane, cycle["3-1"], law).best is not None
    assert ENERGY.reduction == "peak"


def test_a_sweep_of_one_sample_runs_the_default_start(crane, cycle):
    """On 1-2 mid-stroke is out of reach; one sample is the default start, the reachable value
    nearest mid-stroke, and its motion is the one the baseline runs."""
    segment = cycle["1-2"]
    values, q = default_start(crane, segment, ["x3"])
    search = improved_start(crane, segment, VELOCITY, samples=1, method="sweep")
    assert len(search.samples) == 1 and search.samples[0].values == tuple(values)
    assert search.best is not None
    assert search.best.peak == pytest.approx(
        simulate(crane, VELOCITY.resolver, segment, q[None]).peak_velocity_norm[0], rel=1e-3
    )


def test_one_sample_is_the_default_start_for_two_held_actuators_and_for_a_whole_cycle(crane, cycle):
    """The compass search of several held actuators and the whole cycle's sweep take one
    sample as a segment's sweep does: the default start, not the middle of the box or of the
    stroke (out of reach at the paper's point 1)."""
    robot = load_robot("hiab031", task_axes="x")
    segment = Segment("in", np.array([3.0]), np.array([2.0]), 0.5)
    held = ("x2", "x3")
    values, _ = default_start(robot, segment, held)
    search = improved_start(robot, segment, VELOCITY, held, samples=1)
    assert search.samples[0].values == tuple(values)
    assert search.best is not None
    first = default_start(crane, cycle.segments[0], ["x3"])[0]
    whole = improved_cycle_start(crane, cycle, VELOCITY, samples=1, method="sweep")
    assert [s.values for s in whole.samples] == [tuple(first)]
    assert whole.samples[0].peak is not None


PLANAR_ARM = Path(__file__).parent / "data" / "planar4r"


def test_the_compass_search_polls_along_bases_that_turn_round_by_round():
    """Each round's poll directions are an orthonormal basis (± its rows); the first is the held
    actuators' own axes, and over the rounds the directions fill the circle (r = 2): no gap of
    more than 20° between the directions of 30 rounds."""
    bases = starts._poll_bases(2, starts.REFINEMENT_ROUNDS)
    for basis in bases:
        np.testing.assert_allclose(basis @ basis.T, np.eye(2), atol=1e-14)
    np.testing.assert_allclose(np.abs(bases[0]), [[0, 1], [1, 0]], atol=1e-14)
    angles = np.sort(np.concatenate([np.arctan2(b[:, 1], b[:, 0]) for b in bases]) % np.pi)
    assert np.degrees(np.diff(np.append(angles, angles[0] + np.pi))).max() < 20
    four = starts._poll_bases(4, starts.REFINEMENT_ROUNDS)
    np.testing.assert_allclose(
        four @ four.transpose(0, 2, 1), np.broadcast_to(np.eye(4), four.shape), atol=1e-14
    )


def test_the_compass_search_follows_a_limit_oblique_to_the_held_strokes():
    """A peak v₁ + 3 v₂ + 10 over two held strokes [−2.9, 2.9], feasible where v₁ + v₂ ≥ 0.5:
    its least value, 5.7, lies at (2.9, −2.4), where that limit meets the box. At a point of
    the limit every poll along a stroke either leaves the feasible set or raises the peak, so
    the axes alone stalled at the first such point (5.93, 0.15 from the corner); the turning
    bases reach the corner to the search's finest step (1/1000 of the stroke, 5.8 mm)."""
    arm = load_robot(PLANAR_ARM / "robot.toml")

    def run(values, extending=False):
        samples = tuple(
            starts.Sample(tuple(v), v[0] + 3 * v[1] + 10, v[0] + v[1] >= 0.5)
            for v in values.tolist()
        )
        return starts.SearchResult(
            arm, None, VELOCITY, ("x3", "x4"), samples, (), np.full(len(samples), -1)
        )

    best = starts._compass(arm, None, ("x3", "x4"), 100, run).best
    assert np.linalg.norm(np.subtract(best.values, (2.9, -2.4))) < 5.8e-3
    assert best.peak == pytest.approx(5.7, abs=2 * 5.8e-3)


def test_a_compass_round_whose_trials_are_all_unreachable_does_not_end_the_search():
    """The planar 4R arm holding joints 1 and 4 from (1, 0) m: much of that box is out of reach,
    and a round of the compass refinement whose trials all fall outside it is recorded
    (unreachable samples, no motion), as a fast search's round is; it used to end the search in
    "cannot reach the start ... from any of the 12 sampled values"."""
    arm = load_robot(PLANAR_ARM / "robot.toml")
    segment = Segment("out", np.array([1.0, 0.0]), np.array([2.2, 0.2]), 0.3)
    search = improved_start(arm, segment, VELOCITY, ("x1", "x4"), samples=2000)
    trials = search.samples[2000:]
    rounds = [trials[i : i + 12] for i in range(0, len(trials), 12)]  # 3 leaders × 4 directions
    assert any(all(s.peak is None for s in batch) for batch in rounds)
    assert search.best is not None and search.best.feasible


def test_a_start_out_of_reach_at_mid_stroke_is_continued_from_one_with_the_held_actuator_free(
    crane, paper_cycle
):
    """The paper's point 1 is out of reach with the telescope at mid-stroke: the fast search's
    configurations then continue from those found at other strokes and with the telescope free.
    They are the configurations multi-seed inverse kinematics finds at each reachable stroke,
    to Newton's tolerance."""
    segment = paper_cycle["1-2"]
    configurations = starts.Configurations.branches(crane, segment, "x3")[0]
    middle = np.mean(starts.stroke_box(crane, ("x3",))[0])
    assert not inverse_kinematics(crane, segment.start, ["x3"], [[middle]]).reached[0]
    pieces = configurations.reachable(starts.end_tolerance(crane, "x3", None))
    values = np.concatenate([np.linspace(low, high, 12) for low, high in pieces])
    continued = configurations.at(values)
    solved = inverse_kinematics(crane, segment.start, ["x3"], values[:, None])
    assert solved.reached.all()
    np.testing.assert_allclose(continued.q, solved.q, atol=1e-9)


def test_an_objective_may_be_named(crane, paper_cycle):
    """improved_start takes an objective's name as the objective itself."""
    named = improved_start(crane, paper_cycle["1-2"], "energy")
    given = improved_start(crane, paper_cycle["1-2"], ENERGY)
    assert named.objective is ENERGY
    assert [s.values for s in named.samples] == [s.values for s in given.samples]
    assert named.best_peak == given.best_peak


def test_a_round_whose_probes_are_all_unreachable_does_not_end_the_search(crane, paper_cycle):
    """Probes of a round that all fall where no configuration reaches the start inside the
    joint limits (the paper's point 1 with the telescope near mid-stroke) are recorded as
    unreachable samples, each saying why, with no motion, and the search goes on from the
    samples before them; it used to end in "cannot reach the start ... from any of the 3
    sampled values", as a first batch out of reach still does."""
    segment = paper_cycle["1-2"]
    configurations = starts.Configurations.branches(crane, segment, "x3")[0]
    middle = np.mean(starts.stroke_box(crane, ("x3",))[0])
    probes = configurations.at(middle + np.array([-0.01, 0.0, 0.01]))
    assert not probes.reachable.any()

    def run(values, extending=False):
        return evaluate_starts(crane, segment, VELOCITY, "x3", values, extending=extending)

    with pytest.raises(UnreachableError, match="from any of the 3 sampled values of x3"):
        run(probes)
    first = run(configurations.at(np.linspace(0.8, 1.09, 4)))
    extended = first.extended(run(probes, extending=True))
    assert extended.samples[:4] == first.samples and extended.best == first.best
    assert all(s.peak is None and "start unreachable" in s.reason for s in extended.samples[4:])
    assert probes.reason(1) == "start unreachable (no configuration on this branch reaches it)"
    assert len(extended.samples) == 7 and extended.simulations == first.simulations


def test_the_fast_search_keeps_to_the_side_of_the_fold_of_its_branch(tmp_path):
    """The Panda with its wrist locked, holding joint 3: inverse kinematics reaches the start at
    mid-stroke on one branch, and continuation along joint 3 keeps every start on its side of
    the fold (det [J; A_h] of one sign). Beyond a band of values the arm reaches only outside
    its other joints' limits it used to land on the other side, and 16 of the search's 25
    starts mixed that branch into this one's. Its best is no worse than a 40-sample sweep's,
    which takes inverse kinematics' pick at each value, on either side."""
    (tmp_path / "robot.toml").write_text(
        'urdf = "package://example-robot-data/robots/panda_description/urdf/panda.urdf"\n'
        "locked_joints = {panda_finger_joint1 = 0.04, panda_finger_joint2 = 0.04, "
        "panda_joint5 = 0.0, panda_joint6 = 1.8, panda_joint7 = 0.8}\n"
        'tool_frame = "panda_hand_tcp"\ntask_axes = "xyz"\npayload = 0.0\ntask = "task.toml"\n'
    )
    (tmp_path / "task.toml").write_text(
        'name = "wrist locked"\nspeed = 0.25\nsegments = ["pick-lift"]\nheld = ["panda_joint3"]\n'
        "[points]\npick = [0.55, -0.25, 0.25]\nlift = [0.45, 0.0, 0.55]\n"
    )
    with pytest.warns(UserWarning):  # the Panda's joints are driven directly
        arm = load_robot(tmp_path / "robot.toml")
    segment = WorkCycle.from_toml(arm.task_file, dimension=arm.m)["pick-lift"]
    fast = improved_start(arm, segment, VELOCITY, held="panda_joint3")
    sweep = improved_start(arm, segment, VELOCITY, held="panda_joint3", method="sweep", samples=40)
    reached = [fast.start_configuration(s) for s in fast.samples if s.peak is not None]
    row = arm.actuators.names.index("panda_joint3")
    sides = fold_side(evaluate(arm, np.array(reached)), [row])
    assert len(reached) > 10 and np.all(sides == sides[0])
    assert fast.best.feasible and fast.best_peak <= sweep.best_peak


@pytest.mark.parametrize("method", ["fast", "sweep"])
def test_the_improved_start_searches_every_elbow_that_reaches_the_start(method):
    """The slewing 3R arm along a line across its reach, x3 held: both elbows reach the line's
    start at mid-stroke, and the one inverse kinematics picks first has the higher least peak
    (0.1096 rad²/s² against 0.0739). Each search finds the other's start, against a brute
    force over 561 values of x3 on each elbow from closed-form configurations; on the first
    elbow alone it found 0.1096."""
    robot = load_robot(SLEWING / "robot.toml")
    line = WorkCycle.from_toml(SLEWING / "line.toml", dimension=robot.m)["a-b"]
    least = {}
    for elbow in (1, -1):
        found = [start_configuration(v, elbow, line.start) for v in np.linspace(-2.8, 2.8, 561)]
        q = np.array([each for each in found if each is not None and abs(each[1]) <= 2.8])
        motions = simulate(robot, VELOCITY.resolver, line, q)
        peaks = np.where(motions.within_limits, motions.score(VELOCITY), np.inf)
        least[elbow] = (peaks.min(), q[np.argmin(peaks)])
    assert least[1][0] > 1.4 * least[-1][0]  # the elbows differ
    search = improved_start(robot, line, VELOCITY, "x3", samples=561, method=method)
    peak, start = least[-1]
    assert search.best_peak == pytest.approx(peak, rel=2e-4)
    assert robot.same_pose(search.motion().q[0, 0], start, 0.02)


def test_a_slew_held_over_one_turn_is_searched_on_both_elbows_beyond_the_stroke_end():
    """The slewing arm's line with its slew x1 held over a stroke of one turn: mid-stroke does
    not reach the start, and the slews that do run across the stroke's end (from 168° through
    ±180° to −64°). The least peak over both elbows, by brute force over x1 in steps of 0.25°
    from the closed form, lies on the elbow up just short of 180° (0.0739 rad²/s² at 173.4°),
    cut off along x1 from the rest of that elbow by the stroke's end. The search found 0.0942
    there, on the elbow down: its one search was seeded by configurations of both elbows, and
    continuation jumped between them."""
    robot = load_robot(SLEWING / "slew_held.toml")
    line = WorkCycle.from_toml(SLEWING / "line.toml", dimension=robot.m)["a-b"]
    values = np.radians(np.arange(-180.0, 180.0, 0.25))
    least = {}
    for elbow in (1, -1):
        found = [slew_held_configuration(v, elbow, line.start) for v in values]
        q = np.array([each for each in found if each is not None and np.all(abs(each[1:]) <= 2.8)])
        motions = simulate(robot, VELOCITY.resolver, line, q)
        least[elbow] = np.where(motions.within_limits, motions.score(VELOCITY), np.inf).min()
    assert least[1] < 0.8 * least[-1]
    search = improved_start(robot, line, VELOCITY, "x1")
    assert search.best_peak <= least[1] * (1 + 2e-4)
    best = search.start_configuration(search.best)
    up = slew_held_configuration(search.best.value, 1, line.start)
    assert np.abs(modulo_turn(best - up)).max() < 1e-6


def test_the_report_names_the_configuration_of_the_best_start():
    """On the slewing arm's line both elbows reach the start at every held x3 near the best, so
    the held value alone does not name the start: the report gives every actuator's stroke
    there (x = q), those of the elbow the search chose, as the closed form puts it."""
    robot = load_robot(SLEWING / "robot.toml")
    line = WorkCycle.from_toml(SLEWING / "line.toml", dimension=robot.m)["a-b"]
    best = best_report(improved_start(robot, line, VELOCITY, "x3"))
    assert list(best["strokes"]) == ["x1", "x2", "x3"]
    strokes = np.array(list(best["strokes"].values()))
    assert strokes[2] == pytest.approx(best["value"], abs=1e-9)
    chosen, other = (start_configuration(best["value"], e, line.start) for e in (-1, 1))
    assert robot.same_pose(strokes, chosen, 1e-6)
    assert other is not None and not robot.same_pose(strokes, other, 0.1)
    assert list(best["joints"]) == ["j1", "j2", "j3"]
    assert robot.same_pose(np.array(list(best["joints"].values())), chosen, 1e-6)


def test_mirrored_branches_are_a_tie_and_the_first_is_kept():
    """The slewing arm's circle about its base is one task on either elbow, mirrored: the
    kinetic-energy objective's best peaks on the two differ by 1e-10 of their value (by
    1.1e-6 at the samples), and the elbow inverse kinematics picks first is kept, not the one
    the integration's noise favours (which moved the best start from -95° to 15°)."""
    robot = load_robot(SLEWING / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    search = improved_start(robot, cycle, ENERGY, "x3")
    value = search.best.value
    assert robot.same_pose(
        search.start_configuration(search.best), start_configuration(value, 1, cycle.start), 1e-6
    )


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
def test_a_sweep_whose_samples_all_miss_begins_where_free_configurations_reach_the_start():
    """The Panda holding four joints, its tool 0.7 m out: the held values that reach the point
    are a small part of the stroke box, and 16 Halton samples all miss it (as 256 candidates of
    the default start do). Both then begin from the held values of configurations that reach
    the point with every actuator free: the sweep integrates motions that start on the point,
    and the default start reaches it, where both refused the point as out of reach."""
    robot = load_robot("panda")
    held = tuple(robot.actuators.names[3:])
    segment = Segment("out", np.array([0.7, 0.0, 0.4]), np.array([0.7, 0.05, 0.4]), 0.1)
    box = starts.stroke_box(robot, held)
    halton = starts._halton(box, 16, seed=1)
    assert not inverse_kinematics(robot, segment.start, held, halton).reached.any()
    search = improved_start(robot, segment, VELOCITY, held=held, samples=16)
    assert search.simulations >= 1
    for sample in (s for s, row in zip(search.samples, search.rows) if row >= 0):
        q = search.start_configuration(sample)
        np.testing.assert_allclose(evaluate(robot, q[None]).y[0], segment.start, atol=1e-9)
        x_held = evaluate(robot, q[None]).x[0, [robot.actuators.names.index(h) for h in held]]
        np.testing.assert_allclose(x_held, sample.values, atol=1e-9)
    values, q = starts.default_start(robot, segment, held)
    space = evaluate(robot, q[None])
    np.testing.assert_allclose(space.y[0], segment.start, atol=1e-9)
    np.testing.assert_allclose(space.x[0, robot.actuators.rows(held)], values, atol=1e-9)
    far = Segment("far", np.array([3.0, 0.0, 1.0]), np.array([3.1, 0.0, 1.0]), 0.1)  # no reach
    for search in (
        lambda: improved_start(robot, far, VELOCITY, held=held, samples=16),
        lambda: starts.default_start(robot, far, held),
    ):
        with pytest.raises(UnreachableError, match="panda cannot reach the start"):
            search()


def test_a_dynamic_objectives_best_start_is_the_least_on_the_grid_among_its_samples():
    """The excavator's LS pump energy along 3-1. The figure at sparse samples reads ẍ from
    differences of ẋ between the steps, 4 % low for the start at 1.3515 m, which it ranked
    first (20.03 kJ on the grid), where a 40-sample sweep holds a start that keeps every limit
    at 19.58 kJ. Ranked again on the grid, the search's best start is at most the sweep's."""
    from redundancy import LS_ENERGY
    from redundancy.planning.integrate import REPORT_TOLERANCE

    robot = load_robot("excavator")
    segment = WorkCycle.from_toml(robot.task_file, dimension=robot.m)["3-1"]
    search = improved_start(robot, segment, LS_ENERGY, held="bucket")
    sweep = improved_start(robot, segment, LS_ENERGY, held="bucket", method="sweep", samples=40)
    starts = np.array([sweep.start_configuration(sample) for sample in sweep.feasible])
    grid = simulate(
        robot, LS_ENERGY.resolver, segment, starts, tolerance=REPORT_TOLERANCE, objective=LS_ENERGY
    )
    least = np.where(grid.within_limits, grid.score(LS_ENERGY), np.inf).min()
    assert search.best_peak <= least * (1 + 1e-3)
    assert search.best_motion.within_limits[0]
