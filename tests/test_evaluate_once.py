"""Every state is evaluated once: the study's own computations on a paper segment send each
configuration through the one Pinocchio pass about once, and the motions the product reports
keep the power balance on their own grid."""

import numpy as np
import pytest
from counting import counting
from joint_space import mechanical_energy

from redundancy.errors import InvalidInputError
from redundancy.planning.bound import global_optimum
from redundancy.planning.cycles import plan_cycle
from redundancy.planning.ik import ITERATIONS, _seeds, newton
from redundancy.planning.integrate import rate_on_grid
from redundancy.planning.starts import default_start, improved_start, improved_starts
from redundancy.resolution.objectives import ENERGY, VELOCITY
from redundancy.study.peers import StrategyRun, fixed_start_run
from redundancy.study.study import (
    BASELINES,
    STUDY_CYCLES,
    Searches,
    cycle_section,
    run_study,
    study_searches,
)
from redundancy.viz.playback import write_playbacks
from redundancy.viz.plots import pyplot, study_figures, write_figures

OBJECTIVES = (VELOCITY, ENERGY)
SEGMENTS = ("1-2", "2-3", "3-1")


@pytest.fixture(scope="module")
def searches(crane, paper_cycle):
    """Each paper segment's improved start for both objectives, the strokes of the lift and
    fold cylinders checked (every segment then has a best start for both)."""
    return {
        (name, objective.name): improved_start(
            crane, paper_cycle[name], objective, checked=("x1", "x2")
        )
        for name in SEGMENTS
        for objective in OBJECTIVES
    }


def test_a_segments_study_evaluates_each_state_about_once(crane, paper_cycle):
    """What the study (``--method sweep``) computes on segment 1-2 before its bound: the
    default start, the baselines, the sweep for both objectives and the motions it reports,
    and every run's figures (forces, flows, energies, shortest duration). Each state goes
    through the one Pinocchio pass once, give or take 5 %."""
    segment = paper_cycle["1-2"]
    with counting() as counts:
        start = default_start(crane, segment, ["x3"])
        runs = [
            fixed_start_run(crane, resolver, name, segment, ["x3"], start)
            for name, resolver in BASELINES
        ]
        for search in improved_starts(crane, segment, OBJECTIVES, ["x3"], method="sweep"):
            runs.append(StrategyRun(segment.name, "improved", [0.0], search.best_motion))
        for run in runs:
            run.summary()
    assert counts.distinct > 10_000
    assert counts.evaluated <= 1.05 * counts.distinct, counts.ratio


def test_the_search_and_the_bound_evaluate_each_state_about_once(crane, paper_cycle):
    """The fast search and the bound on segment 1-2 for both objectives: Newton's states at the
    nodes are the transcription's, and a node the solver left where it was keeps its states,
    so each state goes through the one Pinocchio pass once, give or take 5 %."""
    segment = paper_cycle["1-2"]
    with counting() as counts:
        for search in improved_starts(crane, segment, OBJECTIVES, ["x3"]):
            global_optimum(crane, segment, search.objective, "x3", search=search)
    assert counts.distinct > 10_000
    assert counts.evaluated <= 1.05 * counts.distinct, counts.ratio


def test_the_whole_study_evaluates_each_state_about_once(crane, paper_cycle, tmp_path):
    """What `redundancy study` computes, in one process as `benchmarks/evaluations.py` counts
    it: the improved searches first, the study of the paper's segments, every run's figures,
    the figures and playbacks, and the cycle section (the command's second process), whose
    per-segment plan reads the study's searches. Each state goes through the one Pinocchio pass
    once, give or take 5 %."""
    with counting() as counts:
        searches = study_searches(crane, paper_cycle, OBJECTIVES)
        study = run_study(
            crane, paper_cycle, OBJECTIVES, progress=False, cycles=0, searches=searches
        )
        write_figures(study, tmp_path)
        write_playbacks(study, tmp_path)
        for run in study.runs:
            run.summary()
        section, skipped = cycle_section(
            crane, paper_cycle, VELOCITY, STUDY_CYCLES, segments=searches.first()
        )
    assert section is not None, skipped
    assert section.plan.segments == searches.first()
    assert counts.distinct > 100_000
    assert counts.evaluated <= 1.05 * counts.distinct, counts.ratio


def test_the_study_figures_only_read_finished_numbers(crane, paper_cycle):
    """The study computes every motion its figures draw, Fig. 4c's non-optimal one too
    (`Study.nonoptimal`): drawing them sends no state through the pass."""
    study = run_study(
        crane, paper_cycle, OBJECTIVES, samples=12, bound=False, progress=False, cycles=0
    )
    with counting() as counts:
        figures = study_figures(study)
    for figure in figures.values():  # pyplot keeps them open; the next test's count would warn
        pyplot().close(figure)
    assert "fig4c_nonoptimal_velocity_1-2.png" in figures
    assert counts.evaluated == 0


def test_searches_made_otherwise_are_refused(crane, paper_cycle):
    """Searches are read only where they were made with the same arguments: a study refuses
    searches made for other objectives, and the cycle plan a per-segment plan that is not one
    search of its objective per segment, before any work."""
    other = Searches(("x3",), "fast", {}, (("energy",), 100, None, None, False, False))
    with pytest.raises(InvalidInputError, match="the searches were made with"):
        run_study(crane, paper_cycle, (VELOCITY,), progress=False, searches=other)
    with pytest.raises(InvalidInputError, match="segments must be one search of 'velocity'"):
        plan_cycle(crane, paper_cycle, VELOCITY, segments=())


@pytest.mark.parametrize("objective", [o.name for o in OBJECTIVES])
@pytest.mark.parametrize("name", SEGMENTS)
def test_reported_motions_keep_the_power_balance_on_their_grid(crane, searches, name, objective):
    """Σ F_i ẋ_i = d/dt (T + V) along the best motion a search reports, on its own 10 ms grid:
    within 1e-5 of the peak power (the rate of T + V by the same fourth-order differences as
    ẍ; at the search's tolerance the dense output's rate misses the law's by 1e-4)."""
    motion = searches[name, objective].best_motion
    t, q = motion.t[0], motion.q[0]
    assert t[1] - t[0] <= 0.01
    v = motion.states.v.reshape(q.shape)
    power = np.einsum("ti,ti->t", motion.forces[0], motion.x_dot[0])
    stored = rate_on_grid(mechanical_energy(crane, q, v)[None], t)[0]
    inside = slice(2, -2)
    error = np.abs(power[inside] - stored[inside]).max()
    assert error <= 1e-5 * np.abs(power).max(), error


def test_newton_passes_a_configuration_it_clips_rows_to_once(crane):
    """Bounded Newton from 8 seeds towards a point 6 m out, beyond the crane's reach, for two
    telescope lengths: most rows run to one corner of the joint box (q1 and q2 at their limits,
    the telescope at its longest), each in an iteration of its own, for either length. Each
    distinct configuration goes through the pass once all the same."""
    targets = np.array([[6.0, 3.0, 0.7], [6.0, 3.0, 0.9]])
    guess = np.tile(_seeds(crane, 8), (2, 1))
    with counting() as counts:
        solved = newton(crane, guess, [2], np.repeat(targets, 8, axis=0), ITERATIONS, True)
    assert np.all(solved.miss > 2.0)  # out of reach: none converged
    corner = np.array([crane.lower[0], crane.upper[1], crane.upper[2]])
    at_corner = np.all(solved.q == corner, axis=1)
    assert at_corner[:8].sum() >= 2 and at_corner[8:].sum() >= 2, solved.q
    assert counts.evaluated == counts.distinct, counts.ratio
