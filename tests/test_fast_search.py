"""The fast improved search against the paper's uniform sweep, and its lean law against the
resolvers. The sweeps here are coarser than the benchmark's (23 samples at 0.02 s, refined
locally at the 1,000-sample spacing where the best start lies) to keep the tests quick."""

import dataclasses

import numpy as np
import pytest
from sampling import random_configurations

import redundancy.fast_search as fast_search
import redundancy.resolvers as resolvers
from redundancy import InvalidInputError, actuator_space, bundled_robots, load_robot
from redundancy.fast_search import FastResolver, fast_start, integrate, stroke_extremes
from redundancy.ik import inverse_kinematics
from redundancy.initial_configuration import evaluate_starts, improved_start
from redundancy.objectives import ENERGY, VELOCITY
from redundancy.resolvers import GradientProjection
from redundancy.simulate import simulate
from redundancy.tasks import WorkCycle

SEGMENTS = ["1-2", "2-3", "3-1"]
COARSE = 23  # samples of the test's uniform sweep
DENSE = 1000  # the benchmark's reference sweep, whose spacing the local refinement uses


@pytest.fixture(scope="module")
def cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


@pytest.fixture(scope="module")
def searches(crane, cycle):
    return {name: fast_start(crane, cycle[name]) for name in SEGMENTS}


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize("name", bundled_robots())
@pytest.mark.parametrize("objective", [VELOCITY, ENERGY], ids=lambda o: o.name)
def test_lean_law_equals_the_resolvers_on_every_bundled_robot(name, objective):
    robot = load_robot(name)
    q = random_configurations(robot, 25, seed=40, margin=0.05)
    y_dot = np.random.default_rng(41).normal(scale=0.5, size=(25, robot.m))
    space = actuator_space(robot, q)
    expected = objective.resolver.resolve(space, y_dot)
    law = FastResolver(robot, objective)
    rates = law.rates(q, y_dot)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(rates.x_dot, expected, atol=1e-12 * scale)
    np.testing.assert_allclose(rates.state.x, space.x, atol=1e-12)
    np.testing.assert_allclose(rates.state.J, space.J, atol=1e-12)
    weight = np.broadcast_to(np.eye(robot.n), space.A.shape) if objective is VELOCITY else space.M_H
    measure = np.einsum("ki,kij,kj->k", expected, weight, expected)
    np.testing.assert_allclose(rates.measure, measure, rtol=1e-10)
    steps = np.array([law.step(qi, yi).x_dot for qi, yi in zip(q, y_dot)])
    np.testing.assert_allclose(steps, expected, atol=1e-12 * scale)


@pytest.mark.parametrize("objective", [VELOCITY, ENERGY], ids=lambda o: o.name)
def test_lean_law_damps_like_the_resolvers_where_damping_is_due(crane, monkeypatch, objective):
    """With the singularity threshold raised until every state counts as near singular, both
    paths take the damped branch, which changes the answer, and still agree."""
    q = random_configurations(crane, 20, seed=42, margin=0.05)
    y_dot = np.random.default_rng(43).normal(scale=0.5, size=(20, crane.m))
    space = actuator_space(crane, q)
    undamped = objective.resolver.resolve(space, y_dot)
    monkeypatch.setattr(resolvers, "SINGULAR_RATIO", 1.0)
    monkeypatch.setattr(fast_search, "SINGULAR_RATIO", 1.0)
    damped = objective.resolver.resolve(space, y_dot)
    assert np.abs(damped - undamped).max() > 1e-3 * np.abs(undamped).max()
    law = FastResolver(crane, objective)
    np.testing.assert_allclose(law.rates(q, y_dot).x_dot, damped, atol=1e-12)
    steps = np.array([law.step(qi, yi).x_dot for qi, yi in zip(q, y_dot)])
    np.testing.assert_allclose(steps, damped, atol=1e-12)


def test_hermite_extremes_find_a_maximum_between_samples():
    """x = sin t sampled at 0, 1, 2 s: the maximum 1 at t = π/2 lies between samples."""
    t = np.array([[0.0, 1.0, 2.0]])
    x = np.sin(t)[..., None]
    lowest, highest = stroke_extremes(t, x, np.cos(t)[..., None])
    assert highest[0, 0] == pytest.approx(1.0, abs=5e-3) and highest[0, 0] > np.sin(2.0)
    assert lowest[0, 0] == pytest.approx(np.sin(1.0))  # the start itself is excluded


def test_adaptive_motions_agree_with_simulate_within_the_error_allowance(crane, cycle):
    segment = cycle["3-1"]
    ik = inverse_kinematics(crane, segment.start, ["x3"], np.array([[0.6], [0.75], [0.9]]))
    reference = simulate(crane, VELOCITY.resolver, segment, ik.q, time_step=0.005)
    motion = integrate(FastResolver(crane), segment, ik.q)
    lowest, highest = stroke_extremes(motion.t, motion.x, motion.x_dot)
    lowest, highest = np.minimum(lowest, motion.x[:, 0]), np.maximum(highest, motion.x[:, 0])
    allowance = fast_search.ALLOWANCE * fast_search.INTEGRATION_TOLERANCE
    assert np.abs(lowest - reference.x.min(axis=1)).max() < allowance
    assert np.abs(highest - reference.x.max(axis=1)).max() < allowance
    np.testing.assert_allclose(motion.x[:, -1], reference.x[:, -1], atol=allowance)
    np.testing.assert_allclose(motion.measure.max(axis=1), reference.peak_velocity_norm, rtol=1e-3)


@pytest.mark.parametrize("name", SEGMENTS)
def test_fast_search_and_uniform_sweep_agree(crane, cycle, searches, name):
    """Same feasible range within one sample spacing; same best peak within 0.5% of the best a
    1,000-sample sweep finds (the sweep's peak falls over its feasible range, so that best lies
    within one coarse spacing above the coarse sweep's best, where the 1,000-sample grid is
    swept)."""
    segment, fast = cycle[name], searches[name]
    sweep = improved_start(crane, segment, VELOCITY, "x3", COARSE, time_step=0.02)
    spacing = 1.09 / (COARSE - 1)
    assert np.abs(np.subtract(fast.feasible_range, sweep.feasible_range)).max() <= spacing
    peaks = [s.peak for s in sweep.feasible]
    assert np.all(np.diff(peaks) < 0) and sweep.best == sweep.feasible[-1]
    grid = np.linspace(0.0, 1.09, DENSE)
    local = grid[(grid >= sweep.best.value) & (grid <= sweep.best.value + spacing)]
    dense = evaluate_starts(crane, segment, VELOCITY, "x3", local, time_step=0.02).best
    assert abs(fast.best.peak - dense.peak) / dense.peak < 0.005
    assert fast.best.value >= dense.value - 1.09 / (DENSE - 1)


@pytest.mark.parametrize("name", SEGMENTS)
def test_fast_searchs_best_start_keeps_every_stroke_under_simulate(searches, name):
    motion = searches[name].motion()
    assert motion.within_limits[0], motion.violations(0)
    assert VELOCITY.peak(motion)[0] == pytest.approx(searches[name].best.peak, rel=1e-3)


def test_fast_search_needs_few_simulations(searches):
    """A fraction of the paper's 100 samples; the feasible ends located to the tolerance."""
    for fast in searches.values():
        assert fast.simulations < 40 and fast.rounds <= 3


def test_fast_search_rejects_bad_arguments(crane, cycle):
    segment = cycle["1-2"]
    with pytest.raises(InvalidInputError, match="grid"):
        fast_start(crane, segment, grid=2)
    with pytest.raises(InvalidInputError, match="x9"):
        fast_start(crane, segment, held="x9")
    with pytest.raises(InvalidInputError, match="unknown actuators"):
        fast_start(crane, segment, checked=("x1", "y7"))
    with pytest.raises(InvalidInputError, match="GradientProjection"):
        FastResolver(crane, dataclasses.replace(VELOCITY, resolver=GradientProjection(0.1)))
