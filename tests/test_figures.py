"""The study's figures say what they draw: the motion figures on a segment that has a feasible
start, titles whole."""

import pytest

from redundancy import VELOCITY, WorkCycle, load_robot, run_study
from redundancy.study.study import write_report
from redundancy.viz.plots import pyplot, study_figures, write_pngs
from redundancy.viz.report import write_index

# The paper's points with 3 raised out of 2-3's reach (no start keeps its strokes), 2-3 first.
LATE_TASK = (
    'segments = ["2-3", "3-1", "1-2"]\n[points]\n1 = [3.5, -0.5]\n2 = [1.0, -0.5]\n'
    "3 = [2.25, 4.45]\n"
)


# The crane along world x alone, the fold and the telescope held: a closed cycle of two
# segments whose names make the motion figures' titles long.
LINE_TASK = """held = ["x2", "x3"]
segments = [
  { from = "a", to = "b", name = "reach-out" },
  { from = "b", to = "a", name = "pull-back" },
]
[points]
a = [2.0]
b = [3.0]
"""


@pytest.fixture(scope="module")
def late_cycle(crane, tmp_path_factory):
    task = tmp_path_factory.mktemp("late") / "late.toml"
    task.write_text(LATE_TASK)
    return WorkCycle.from_toml(task, dimension=crane.m)


@pytest.fixture(scope="module")
def two_held(tmp_path_factory):
    """The line task's study with its cycle section, written as `redundancy study` writes it
    (figures, report, page): its folder and the study."""
    folder = tmp_path_factory.mktemp("two_held")
    robot = load_robot("hiab031", task_axes="x")
    (folder / "line.toml").write_text(LINE_TASK)
    cycle = WorkCycle.from_toml(folder / "line.toml", dimension=1)
    study = run_study(robot, cycle, (VELOCITY,), samples=12, bound=False, progress=False, cycles=2)
    out = folder / "out"
    out.mkdir()
    write_pngs(study_figures(study), out)
    write_report(study, out / "report.json")
    write_index(out)
    return out, study


def test_the_motion_figures_show_the_first_segment_with_a_feasible_start(
    crane, late_cycle, request
):
    """2-3 has no feasible start: Figs. 4b, 4c and the circuit show 3-1, the first segment with
    an improved start, and Fig. 4c starts from the velocity sweep's least extended feasible
    start; nothing is drawn along 2-3."""
    study = run_study(crane, late_cycle, (VELOCITY,), bound=False, progress=False, cycles=0)
    figures = study_figures(study)
    request.addfinalizer(lambda: [pyplot().close(figure) for figure in figures.values()])
    assert study.search("velocity", "2-3").best is None
    shown = {
        "fig4b_best_velocity_3-1.png",
        "fig4c_nonoptimal_velocity_3-1.png",
        "hydraulics_best_velocity_3-1.png",
    }
    assert shown <= set(figures)
    assert not [name for name in figures if "2-3" in name]
    start, motion = study.nonoptimal("3-1")
    feasible = study.sweep("velocity", "3-1").feasible
    assert start.feasible and start == min(feasible, key=lambda s: s.values)
    assert motion.violations(0) == []
    title = figures["fig4c_nonoptimal_velocity_3-1.png"].axes[0].get_title()
    assert "non-optimal feasible start" in title
    assert study.nonoptimal("2-3") is None


def test_fig_4c_is_left_out_where_the_sweep_has_no_feasible_start(crane, late_cycle, request):
    """With 20 samples the velocity sweep misses 3-1's narrow feasible range the search finds:
    Fig. 4b shows 3-1 and no Fig. 4c is drawn from a start that breaks a stroke."""
    study = run_study(
        crane, late_cycle, (VELOCITY,), samples=20, bound=False, progress=False, cycles=0
    )
    figures = study_figures(study)
    request.addfinalizer(lambda: [pyplot().close(figure) for figure in figures.values()])
    assert not study.sweep("velocity", "3-1").feasible
    assert "fig4b_best_velocity_3-1.png" in figures
    assert not [name for name in figures if name.startswith("fig4c_")]


def test_figs_4b_and_4c_share_one_velocity_scale_that_holds_both_motions(
    crane, paper_cycle, request
):
    """On the paper's 1-2 the non-optimal start's velocities exceed the best motion's: the
    scale the two figures share is the union of theirs, so neither curve is cut."""
    study = run_study(
        crane, paper_cycle, (VELOCITY,), samples=20, bound=False, progress=False, cycles=0
    )
    figures = study_figures(study)
    request.addfinalizer(lambda: [pyplot().close(figure) for figure in figures.values()])
    optimal, other = (figures[f"fig4{k}_velocity_1-2.png"] for k in ("b_best", "c_nonoptimal"))
    for figure in (optimal, other):
        figure.canvas.draw()
    assert optimal.axes[1].get_ylim() == other.axes[1].get_ylim()
    low, high = other.axes[1].get_ylim()
    for motion in (study.search("velocity", "1-2").best_motion, study.nonoptimal("1-2")[1]):
        assert low <= motion.x_dot.min() and motion.x_dot.max() <= high


def test_no_title_reaches_past_its_figure(two_held):
    """The motion figures' titles (long with two held starts and long segment names) and the
    peak maps' are broken into lines that lie within the figure as drawn."""
    _, study = two_held
    figures = study_figures(study)
    try:
        for name, figure in figures.items():
            figure.canvas.draw()
            width = figure.bbox.width
            titles = [axes.title for axes in figure.axes]
            titles += [figure._suptitle] if figure._suptitle is not None else []
            for title in titles:
                if title.get_text():
                    extent = title.get_window_extent()
                    assert extent.x0 >= 0 and extent.x1 <= width, (name, title.get_text())
        title = figures["fig4b_best_velocity_reach-out.png"].axes[0].get_title()
        assert "\n" in title.split("dashed")[0]  # it was too long for one line
    finally:
        pyplot().close("all")
