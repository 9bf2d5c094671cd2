"""The study's figures say what they draw: the motion figures on a segment that has a feasible
start, every held actuator shown, titles whole, the page in the tables' words."""

import json
import types

import pandas as pd
import pytest
from lxml import html

from redundancy import VELOCITY, InvalidInputError, WorkCycle, load_robot, run_study
from redundancy.study.study import write_report
from redundancy.viz.map_figures import map_figure
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


def captions(folder) -> dict[str, str]:
    """Each figure's caption on the folder's page, by file name."""
    page = html.fromstring((folder / "index.html").read_text())
    return {
        figure.xpath("img/@src")[0]: figure.xpath("figcaption")[0].text_content()
        for figure in page.xpath("//figure")
    }


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


def test_every_held_actuator_is_drawn_and_captioned(two_held):
    """With two held actuators: the drift figure's lower panel has a curve per held actuator
    and strategy, and the page captions Fig. 4a as the maps it is."""
    out, study = two_held
    figure = study_figures(study)["cycle_drift.png"]
    try:
        below = figure.axes[1]
        drawn = {text.get_text().split(",")[0] for text in below.get_legend().get_texts()}
        assert drawn == {"x2", "x3"}
        assert len(below.get_lines()) == 2 * len(study.cycle_study.repetitions)
        assert below.get_ylabel().startswith("x2 and x3 at the cycle's start")
    finally:
        pyplot().close("all")
    caption = captions(out)["fig4a_peak_velocity.png"]
    assert "hollow" in caption and "red line" in caption and "first two held" in caption
    assert "dotted" not in caption and "shaded" not in caption


def test_the_map_figure_has_a_panel_per_held_actuator(crane, request):
    """The best initial value of each held actuator, one panel each, in its unit."""
    family = types.SimpleNamespace(
        name="two held",
        held=("x2", "x3"),
        held_unit="m",
        grid=(("payload", (0.0, 250.0)),),
        segments=(types.SimpleNamespace(name="1-2"),),
        robot_for=lambda design: crane,
    )
    table = pd.DataFrame(
        {
            "segment": "1-2",
            "objective": "velocity",
            "payload": [0.0, 250.0],
            "feasible": True,
            "default_feasible": pd.array([True, True], dtype="boolean"),
            "gain_pct": [10.0, 12.0],
            "best_x2": [1.1, 1.2],
            "best_x3": [0.9, 1.0],
        }
    )
    figure = map_figure(table, family, "velocity")
    request.addfinalizer(lambda: pyplot().close(figure))
    titles = [axes.get_title() for axes in figure.axes if axes.get_label() != "<colorbar>"]
    assert titles[1:3] == ["best initial x2 (m)", "best initial x3 (m)"]
    # a panel of one value has one tick on its colour bar, that value; a share spans [0, 1]
    table["best_x3"] = 0.95
    table["payload"] = [250.0, 250.001]  # two grid values alike to 3 digits
    figure = map_figure(table, family, "velocity")
    request.addfinalizer(lambda: pyplot().close(figure))
    figure.canvas.draw()
    bars = [axes for axes in figure.axes if axes.get_label() == "<colorbar>"]
    assert [t.get_text() for t in bars[2].get_yticklabels()] == ["0.95"]
    assert bars[3].get_ylim() == (0.0, 1.0)
    ticks = [t.get_text() for t in figure.axes[0].get_yticklabels()]
    assert ticks == ["250", "250.001"]


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


def test_the_page_names_the_search_and_the_price_as_the_tables_do(two_held):
    """With two held actuators the summary names Halton points and compass refinement, not a
    sweep; the drift-free strategy's price uses the strategies' table's words."""
    out, _ = two_held
    text = html.fromstring((out / "index.html").read_text()).text_content()
    assert "Halton points over the held strokes" in text and "compass search" in text
    assert "sweep search" not in text
    price = next(line for line in text.splitlines() if "against the free improved cycle" in line)
    assert "peak ẋᵀẋ" in price and "objective" not in price
    report = json.loads((out / "report.json").read_text())
    versus = report["cycle"]["periodic_versus_free_percent"]
    assert versus and "LS energy per cycle" in price and "ls_energy" not in price


def test_figures_are_closed_when_a_write_fails(tmp_path):
    """A "folder" that is a file cannot take the first figure: the error reaches the caller,
    and none of the figures is left open in pyplot (in a long process, a notebook or a test
    run, they piled up until matplotlib warned of more than 20)."""
    plt = pyplot()
    figures = {f"f{i}.png": plt.figure() for i in range(3)}
    (tmp_path / "file").write_text("")
    with pytest.raises(InvalidInputError, match="is a file, not a folder"):
        write_pngs(figures, tmp_path / "file")
    assert not set(plt.get_fignums()) & {figure.number for figure in figures.values()}
