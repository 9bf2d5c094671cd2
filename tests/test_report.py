"""index.html, the page that gathers an output folder: rendered by headless Chromium, every file
it references exists, every table's segment and strategy appears, every figure has a caption."""

import json
import shutil
import subprocess
from fnmatch import fnmatch

import browser
import numpy as np
import pytest
from commands import run_cli
from lxml import html
from PIL import Image

from redundancy.viz.report import CAPTIONS, write_index


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The study command's output folder: 5 samples, 2 cycles."""
    out = tmp_path_factory.mktemp("study") / "out"
    run = run_cli("study", "--samples", "5", "--cycles", "2", "--out", str(out), "--quiet")
    assert run.returncode == 0, run.stderr
    return out


@pytest.fixture(scope="module")
def rendered(study, tmp_path_factory):
    """The study's index.html as Chromium's DOM holds it once loaded."""
    return html.fromstring(
        browser.dom(study.joinpath("index.html").as_uri(), tmp_path_factory.mktemp("profile"))
    )


def referenced(page) -> list[str]:
    """The files a page's images and links name."""
    return page.xpath("//img/@src") + [h for h in page.xpath("//a/@href") if "://" not in h]


def rows(page) -> list[list[str]]:
    return [[c.text_content().strip() for c in tr.xpath("td")] for tr in page.xpath("//tr[td]")]


def test_the_study_writes_an_index_whose_references_all_exist(study, rendered):
    for name in referenced(rendered):
        assert (study / name).is_file(), name
    written = {p.name for p in study.iterdir()}
    pictures = {n for n in written if n.endswith(".png")}
    playbacks = {n for n in written if n.startswith("playback_")}
    assert pictures and playbacks
    assert set(rendered.xpath("//img/@src")) == pictures  # every figure, each once
    assert playbacks <= set(rendered.xpath("//a/@href"))  # every playback linked
    assert "report.json" in rendered.xpath("//a/@href")


def test_every_figure_has_a_caption_that_explains_it(rendered):
    for figure in rendered.xpath("//figure"):
        name = figure.xpath("img/@src")[0]
        caption = figure.xpath("figcaption")[0].text_content()
        assert caption.startswith(name) and len(caption) > len(name) + 60, name


def test_the_figures_come_in_the_order_the_report_page_describes(rendered):
    """The paper's figures, the circuit (velocity, then energy), the workspace, then the
    cycle's strokes, drift and return map (docs/report.md)."""
    shown = [name.removesuffix(".png") for name in rendered.xpath("//figure/img/@src")]
    assert shown == [
        "fig4a_peak_velocity",
        "fig4b_best_velocity_1-2",
        "fig4c_nonoptimal_velocity_1-2",
        "fig5a_peak_energy",
        "fig5b_best_energy_1-2",
        "hydraulics_best_velocity_1-2",
        "hydraulics_best_energy_1-2",
        "workspace",
        "cycle_strokes",
        "cycle_drift",
        "cycle_return_map",
    ]


def test_every_segment_and_strategy_of_the_report_appears_in_a_table(study, rendered):
    report = json.loads((study / "report.json").read_text())
    shown = rows(rendered)
    for entry in report["comparison"]:
        assert [entry["segment"], entry["strategy"]] in [row[:2] for row in shown], entry
    for study_entry in report["studies"]:
        for segment in study_entry["segments"]:
            assert any(row[:2] == [segment["name"], segment["held_actuator"]] for row in shown)
    for strategy in report["cycle"]["strategies"].values():
        assert any(row[0] == strategy["name"] for row in shown)
    for corner in report["cycle"]["per_segment"]["corners"]:
        assert any(row[0] == f"{corner['after']} → {corner['before']}" for row in shown)


def test_a_withheld_energy_bound_shows_its_reason_not_a_number(study, tmp_path):
    """An energy bound that did not converge is no result: its row has no energy, and why."""
    report = json.loads((study / "report.json").read_text())
    reason = "NOT converged, change 2.22 %"
    withheld = {"energy_kj": None, "change": 0.0222, "converged": False, "grids": [10, 20]}
    report["energy_bounds"] = {"1-2": {"LS": {**withheld, "start": None, "failure": reason}}}
    (tmp_path / "report.json").write_text(json.dumps(report))
    page = html.fromstring(write_index(tmp_path).read_text())
    row = next(row for row in rows(page) if row[:2] == ["1-2", "LS"])
    assert row[2] == "–" and row[-1] == reason


def test_every_table_heading_of_a_quantity_names_its_unit(rendered):
    words = ("peak", "bound (", "energy", "pressure", "flow", "duration", "drift", "length", "Δ")
    words += ("start", "limit cycle")
    headings = [h.text_content() for h in rendered.xpath("//th")]
    quantities = [h for h in headings if any(w in h for w in words) and "%" not in h]
    assert quantities
    for heading in quantities:
        assert heading.rstrip().endswith(")"), heading  # "... (m²/s²)", "(kJ)", "(m)"


def test_the_summary_comes_first_with_the_headline_numbers(study, rendered):
    report = json.loads((study / "report.json").read_text())
    summary = rendered.xpath("//div[@class='summary']")[0]
    assert summary.getparent().index(summary) <= 1  # after the title
    segment = report["studies"][0]["segments"][0]
    best, held = segment["best"], segment["held_actuator"]
    assert f"{best['peak']:.4g} m²/s²" in summary.text_content()
    others = [f"{name} = {x:.4g} m" for name, x in best["strokes"].items() if name != held]
    assert len(others) == 2 and all(text in summary.text_content() for text in others)


def test_the_index_renders_in_a_browser(study, tmp_path):
    shot = tmp_path / "index.png"
    run = subprocess.run(
        browser.command(
            study.joinpath("index.html").as_uri(), tmp_path / "profile", f"--screenshot={shot}"
        ),
        capture_output=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    image = np.asarray(Image.open(shot).convert("L")).astype(int)
    assert image.shape == (768, 1024)
    ink = image < 128
    assert 0.005 < ink.mean() < 0.3  # text and tables drawn, not a blank or a black page
    assert ink[:120].any()  # the title at the top


def test_a_cycle_folder_gets_its_own_index(study, tmp_path):
    """The cycle command's report is the study's cycle object: the page shows its drift."""
    cycle = json.loads((study / "report.json").read_text())["cycle"]
    (tmp_path / "report.json").write_text(json.dumps(cycle))
    shutil.copy(study / "cycle_drift.png", tmp_path)
    page = html.fromstring(write_index(tmp_path).read_text())
    assert "work cycle" in page.xpath("//h1")[0].text_content()
    drift = [h.text_content() for h in page.xpath("//th") if "drift" in h.text_content()]
    assert "largest drift, last cycle (m)" in drift  # the crane's strokes are all lengths
    assert page.xpath("//img/@src") == ["cycle_drift.png"]
    corner = cycle["per_segment"]["corners"][0]["delta"]
    turned = next(name for name in corner if name != cycle["held_actuator"])
    cycle["units"][turned] = "rad"  # each value headed by its own actuator's unit
    (tmp_path / "report.json").write_text(json.dumps(cycle))
    headers = [
        h.text_content() for h in html.fromstring(write_index(tmp_path).read_text()).xpath("//th")
    ]
    assert f"Δ{turned} (rad)" in headers and f"Δ{cycle['held_actuator']} (m)" in headers
    assert "largest drift, last cycle (m or rad)" in headers
    assert not cycle["failures"]  # a part the cycle study left out is said on the page
    cycle["failures"] = {"return map": "the start is out of reach on this branch"}
    (tmp_path / "report.json").write_text(json.dumps(cycle))
    notes = html.fromstring(write_index(tmp_path).read_text()).xpath("//p[@class='note']")
    said = [n.text_content() for n in notes]
    assert "Not computed, return map: the start is out of reach on this branch" in said


def test_a_cycle_with_a_segment_no_start_keeps_gets_its_page(tmp_path):
    """A segment no start keeps within the strokes is a finding, not an error: the cycle command
    writes its report and page, its corners beside that segment with no self-motion and why."""
    task = tmp_path / "high.toml"  # point 3 higher than the paper's: 2-3 passes x2's stroke
    task.write_text(
        'segments = ["1-2", "2-3", "3-1"]\n[points]\n1 = [3.5, -0.5]\n2 = [1.0, -0.5]\n'
        "3 = [2.25, 4.45]\n"
    )
    out = tmp_path / "out"
    run = run_cli(
        "cycle", "--samples", "3", "--cycles", "2", "--task", str(task), "--out", str(out)
    )
    assert run.returncode == 0, run.stderr
    plan = json.loads((out / "report.json").read_text())["per_segment"]
    assert [s["best"] is None for s in plan["segments"]] == [False, True, False]
    assert [c["delta"] is None for c in plan["corners"]] == [True, True, False]
    assert plan["self_motion_time_s"] is None
    page = html.fromstring((out / "index.html").read_text())
    corners = [row for row in rows(page) if "→" in row[0]]
    assert [row[-1] for row in corners[:2]] == ["segment 2-3 has no feasible start"] * 2
    assert corners[0][1:4] == ["–"] * 3  # no Δ of the three actuators
    assert corners[2][-1] == "keeps the strokes"


def test_a_map_folder_gets_its_own_index(tmp_path):
    """Titled by the family's name, not by the folder it was written in (while staged, a hidden
    one)."""
    summary = {"name": "payloads", "summary": "best design: payload 0 kg", "problems": 4}
    (tmp_path / "summary.json").write_text(json.dumps(summary | {"rows": 8}))
    (tmp_path / "map.parquet").write_bytes(b"")
    (tmp_path / "map_velocity.png").write_bytes(b"")
    page = html.fromstring(write_index(tmp_path).read_text())
    assert page.xpath("//title")[0].text == "design map payloads"
    assert "best design: payload 0 kg" in page.text_content()
    assert {"map.parquet", "summary.json", "map_velocity.png"} <= set(referenced(page))
    caption = page.xpath("//figcaption")[0].text_content()
    assert "gain over the default start (%)" in caption
    # the heatmaps in the family's order of objectives, not by name (energy came first)
    summary["objectives"] = ["velocity", "energy"]
    (tmp_path / "summary.json").write_text(json.dumps(summary | {"rows": 8}))
    (tmp_path / "map_energy.png").write_bytes(b"")
    page = html.fromstring(write_index(tmp_path).read_text())
    assert [img.get("src") for img in page.xpath("//img")] == ["map_velocity.png", "map_energy.png"]


def test_each_written_figure_name_has_a_caption():
    names = [
        "fig4a_peak_velocity.png",
        "fig5a_peak_energy.png",
        "figa_peak_flow.png",
        "fig4b_best_velocity_1-2.png",
        "fig4c_nonoptimal_velocity_1-2.png",
        "hydraulics_best_velocity_1-2.png",
        "workspace.png",
        "cycle_strokes.png",
        "cycle_drift.png",
        "cycle_return_map.png",
        "map_velocity.png",
    ]
    for name in names:
        assert any(fnmatch(name, pattern) for pattern, _ in CAPTIONS), name
