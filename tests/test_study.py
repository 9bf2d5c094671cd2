"""The paper's study on the bundled crane, checked against the paper's findings (section 3)."""

import dataclasses
import json
import os
import stat

import numpy as np
import pytest
from commands import run_cli

from redundancy.model.hydraulics import KILOJOULE
from redundancy.model.robot import Robot
from redundancy.planning.integral_optimum import energy_optimum
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import LS_ENERGY
from redundancy.study.output import MARKER, OutputFolder, write_atomically
from redundancy.study.study import run_study
from redundancy.viz.tables import study_table

SEGMENTS = ["1-2", "2-3", "3-1"]


@pytest.fixture(scope="module")
def study(paper_study):
    """40 samples a sweep, a 3-cycle cycle section (conftest: test_cycles shares it)."""
    return paper_study


def width(search):
    return 0.0 if search.feasible_range is None else np.subtract(*search.feasible_range[::-1])


def relative_reduction(search):
    """(worst − best) / worst peak over the feasible samples."""
    peaks = [s.peak for s in search.feasible]
    return (max(peaks) - min(peaks)) / max(peaks)


def test_every_feasible_sample_stays_inside_every_checked_limit(study, crane):
    lower, upper = crane.actuators.lower, crane.actuators.upper
    for searches in [*study.searches.values(), *study.sweeps.values()]:
        for search in searches:
            for i, sample in enumerate(search.samples):
                row = search.rows[i]
                if sample.feasible:
                    x = search.trajectory.x[row]
                    assert np.all((x >= lower - 1e-9) & (x <= upper + 1e-9))
                else:
                    assert sample.reason and sample.margin < -1e-9
                    # past a stroke at a sample, or (sparse samples) between samples or within
                    # the integration allowance of one: the margin says which
                    assert sample.violations or row < 0 or sample.margin > -1e-3


@pytest.mark.parametrize("segment", SEGMENTS)
def test_peak_velocity_norm_falls_as_the_initial_telescope_extension_grows(study, segment):
    """Fig. 4a: the best start is the most extended feasible one, and the gain is substantial."""
    search = study.search("velocity", segment)
    values = [s.value for s in search.feasible]
    peaks = np.array([s.peak for s in search.feasible])
    assert len(values) >= 5 and values == sorted(values)
    assert np.all(np.diff(peaks) <= 1e-9 * peaks[:-1])
    assert search.best.value == search.feasible_range[1]
    assert relative_reduction(search) > 0.4


@pytest.mark.parametrize("segment", SEGMENTS)
def test_energy_objective_gains_marginally_on_a_narrower_feasible_range(study, segment):
    """Fig. 5a: a marginal reduction of the peak kinetic energy and a narrow feasible range."""
    velocity, energy = study.search("velocity", segment), study.search("energy", segment)
    assert width(energy) < width(velocity)
    if energy.feasible:
        assert relative_reduction(energy) < 0.1


def test_velocity_objective_beats_energy_objective_on_segment_1_2(study):
    """The paper's conclusion: the improved min ẋᵀẋ solution has lower actuator velocities."""
    runs = {run.strategy: run.trajectory for run in study.runs if run.segment == "1-2"}
    fast, energetic = runs["improved, velocity objective"], runs["improved, energy objective"]
    assert fast.peak_velocity_norm[0] < energetic.peak_velocity_norm[0]
    assert np.abs(fast.x_dot).max() < np.abs(energetic.x_dot).max()


def test_improved_start_beats_the_default_start_on_every_segment(study):
    for segment in SEGMENTS:
        runs = {r.strategy: r.trajectory for r in study.runs if r.segment == segment}
        improved = runs["improved, velocity objective"]
        plain = runs["unweighted, default start"]
        assert improved.within_limits[0]
        assert improved.peak_velocity_norm[0] <= plain.peak_velocity_norm[0]


def test_the_report_gives_each_best_start_its_motions_peak_and_gap_to_the_bound(study):
    """The best start's peak is its improved run's, the motion on the 10 ms grid; the bound is
    never above it (the gap ≥ 0, up to the bound solver's tolerance)."""
    gaps = 0
    for entry in study.report()["studies"]:
        name, key = entry["objective"], {"velocity": "peak_velocity_norm", "energy": "peak_kinetic"}
        runs = {r.segment: r for r in study.runs if r.strategy == f"improved, {name} objective"}
        for segment in entry["segments"]:
            if segment["best"] is None:
                continue
            run = runs[segment["name"]].summary()
            assert segment["best"]["peak"] == pytest.approx(run[key[name]], rel=1e-12)
            if segment["bound"] is not None:
                gap = 100 * (segment["best"]["peak"] / segment["bound"]["peak"] - 1)
                assert segment["gap_percent"] == pytest.approx(gap, rel=1e-12) and gap > -1e-4
                gaps += 1
    assert gaps == 4  # both objectives on 1-2, velocity on 2-3 and 3-1 (energy has no start)


def test_a_segment_without_a_feasible_start_is_reported_not_raised(study):
    search = study.search("energy", "2-3")
    assert search.best is None and search.feasible_range is None
    assert "x3" in str(search.closest_violation)
    report = study.report()
    energy = next(s for s in report["studies"] if s["objective"] == "energy")
    entry = next(s for s in energy["segments"] if s["name"] == "2-3")
    assert entry["feasible_range"] is None and entry["best"] is None
    assert "past its" in entry["closest_violation"]
    assert "2-3" in study_table(study) and "no sampled start" in study_table(study)


def test_study_command_writes_the_report_and_the_five_figures(tmp_path):
    out = tmp_path / "out"
    run = run_cli("study", "--samples", "5", "--cycles", "2", "--out", str(out), "--quiet")
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["cycle"]["cycles"] == 2 and len(report["cycle"]["per_segment"]["corners"]) == 3
    for name in ("cycle_strokes.png", "cycle_drift.png", "playback_cycle_periodic.html"):
        assert (out / name).is_file()
    assert report["robot"] == "hiab031"
    assert [s["objective"] for s in report["studies"]] == ["velocity", "energy"]
    for entry in report["studies"]:
        assert [s["name"] for s in entry["segments"]] == SEGMENTS
        for segment in entry["segments"]:
            assert segment["held_actuator"] == "x3"
            assert len(segment["samples"]) == 5
            assert {"value", "peak", "feasible"} <= set(segment["samples"][0])
    figures = sorted(p.name for p in out.glob("fig*.png"))
    assert [name[:5] for name in figures] == ["fig4a", "fig4b", "fig4c", "fig5a", "fig5b"]
    for name in figures:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "improved, velocity objective" in run.stdout
    assert (out / "motion_velocity_1-2.csv").read_text().startswith("t (s),q_")
    assert 'href="motion_velocity_1-2.csv"' in (out / "index.html").read_text()


def test_a_study_without_bounds_says_so_where_the_bounds_would_be(tmp_path):
    """``--no-bound`` (a robot of many joints, whose bound takes minutes): the improved starts
    as with bounds, and each bound's place says why it has none."""
    out = tmp_path / "out"
    args = ["--objective", "velocity", "--samples", "5", "--cycles", "0", "--quiet"]
    run = run_cli("study", *args, "--no-bound", "--out", str(out))
    assert run.returncode == 0, run.stderr
    (entry,) = json.loads((out / "report.json").read_text())["studies"]
    assert [s["name"] for s in entry["segments"]] == SEGMENTS
    for segment in entry["segments"]:
        assert segment["bound"] is None and segment["gap_percent"] is None
        assert segment["bound_failure"] == "the study was run without bounds"
        assert segment["best"]["peak"] > 0
    assert run.stdout.count("no bound: the study was run without bounds") == 3
    assert "the study was run without bounds" in (out / "index.html").read_text()


def test_an_integral_objective_s_bound_says_where_it_is(crane, paper_cycle):
    """The min-max bound bounds peaks: an integral objective's place in the bounds table says
    so and where its least value is found, instead of staying blank."""
    study = run_study(crane, paper_cycle, (LS_ENERGY,), samples=3, progress=False, cycles=0)
    for segment in SEGMENTS:
        assert study.bound("ls_energy", segment) is None
        assert study.withheld("ls_energy", segment).startswith("the min-max bound bounds peaks")
    assert study_table(study).count("redundancy.integral_optimum (the pump energy's") == 3


@pytest.mark.parametrize(
    "args, message",
    [
        (["--samples", "0"], "must be a whole number within [1, 10,000]"),
        (["--objective", "speed"], "invalid choice: 'speed'"),
        (["--robot", "hiab32"], "unknown robot 'hiab32'; bundled robots: excavator, hiab031"),
        (["--check", "x1,x9"], "unknown actuators ['x9']"),
        (
            ["--robot", "panda", "--method", "fast"],
            "'panda_joint7'] are 4: use the sweep (method='sweep', --method sweep)",
        ),
    ],
)
def test_bad_study_options_exit_with_a_message_and_no_traceback(tmp_path, args, message):
    run = run_cli("study", "--out", str(tmp_path), "--quiet", *args)
    assert run.returncode == 2
    assert message in run.stderr
    assert "Traceback" not in run.stderr


def test_an_unreachable_segment_point_fails_cleanly_and_keeps_the_old_report(tmp_path):
    task = tmp_path / "far.toml"
    task.write_text(
        'segments = ["1-2"]\nheld = ["x3"]\n[points]\n1 = [9.0, 9.0]\n2 = [1.0, -0.5]\n'
    )
    out = tmp_path / "out"
    with OutputFolder(out) as earlier:
        (earlier / "report.json").write_text('{"previous": true}\n')
    report = out / "report.json"
    run = run_cli("study", "--task", str(task), "--out", str(out), "--quiet")
    assert run.returncode == 2
    assert "cannot follow segment 1-2: its point [9.0, 9.0] m (t = 0 s)" in run.stderr
    assert "Traceback" not in run.stderr
    assert report.read_text() == '{"previous": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.toml", "out"]
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "report.json"]


def test_written_files_get_the_mode_the_umask_gives(tmp_path):
    path = tmp_path / "report.txt"
    previous = os.umask(0o022)
    try:
        write_atomically(path, lambda p: p.write_text("done\n"))
    finally:
        os.umask(previous)
    assert path.read_text() == "done\n"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["report.txt"]


def test_the_report_has_a_cycle_section(study):
    """The paper's three segments form one closed cycle: the study runs it as a machine does."""
    section = json.loads(json.dumps(study.report(), allow_nan=False))["cycle"]
    assert section["objective"] == "velocity" and section["cycles"] == 3
    assert section["whole_cycle"]["best"]["value"] < 0.86  # far below 1-2's own best, 1.09
    corners = section["per_segment"]["corners"]
    assert [(c["after"], c["before"]) for c in corners] == [
        ("1-2", "2-3"),
        ("2-3", "3-1"),
        ("3-1", "1-2"),
    ]
    assert all(c["time_s"] > 0 for c in corners)
    assert set(section["strategies"]) == {"free", "periodic"}
    assert "work cycle 'paper work cycle'" in study_table(study)


def test_the_tables_and_the_report_evaluate_no_state(study, monkeypatch):
    """Every figure the tables and the report show was computed by the study run: with
    Pinocchio's passes refused, both are still written."""

    def refused(*args, **kwargs):
        raise AssertionError("a table or the report evaluated a state")

    for name in ("kinematics", "evaluator", "mass_matrices", "nonlinear"):
        monkeypatch.setattr(Robot, name, refused)
    assert study.robot.hydraulics is not None  # the hydraulic table and the energies too
    table = study_table(study)
    assert "LS kJ" in table and "drift/cycle" in table and "return map" in table
    json.dumps(study.report(), allow_nan=False)


def test_a_task_that_is_no_cycle_has_no_cycle_section(crane):
    cycle = WorkCycle.from_toml(crane.task_file, dimension=crane.m)
    open_task = WorkCycle(cycle.name, cycle.segments[:1], cycle.held)
    study = run_study(crane, open_task, samples=5, bound=False, progress=False)
    assert "does not return to its start" in study.report()["cycle"]["skipped"]


def test_the_table_flags_a_bound_that_has_not_converged(study):
    """A bound whose last refinement moved it by 2 % (more than 0.5 %) is flagged on its row of
    the gap table with that change; the converged ones are not."""
    optimum = study.bounds["velocity"][1]
    assert optimum.converged
    coarse, fine = optimum.grids
    moved = dataclasses.replace(coarse, peak=fine.peak * 1.02)
    unconverged = dataclasses.replace(optimum, grids=(moved, fine))
    velocity = list(study.bounds["velocity"])
    velocity[1] = unconverged
    bounds = dict(study.bounds, velocity=tuple(velocity))
    rows = [
        line
        for line in study_table(dataclasses.replace(study, bounds=bounds)).splitlines()
        if line.split()[:2] in (["1-2", "velocity"], ["2-3", "velocity"], ["3-1", "velocity"])
    ]
    flagged = [row for row in rows if "NOT converged" in row]
    assert len(rows) == 3 and len(flagged) == 1
    assert flagged[0].startswith("2-3") and flagged[0].endswith("NOT converged, change 2.00 %")


def test_an_energy_bound_is_a_result_only_where_it_converged(study, crane):
    """An energy bound that refining its grid (10 → 20 intervals) still moved by over 0.5 % is
    withheld: its table row says "no bound" and why, the report gives null and the reason, and
    no motion is measured against it; a converged one is printed, and one whose solve raised is
    named with the reason."""
    moved = energy_optimum(crane, study.cycle["1-2"], None, "x3", grids=(10, 20))
    assert not moved.converged
    steady = dataclasses.replace(moved, grids=(moved.grids[-1], moved.grids[-1]))
    energetic = dataclasses.replace(study, energy_bounds={"1-2": {"LS": moved, "CP": steady}})
    reason = f"NOT converged, change {100 * moved.change:.2f} %"
    assert energetic.energy_withheld("1-2", "LS") == reason
    assert energetic.energy_result("1-2", "LS") is None
    assert energetic.energy_result("1-2", "CP") is steady
    report = json.loads(json.dumps(energetic.report(), allow_nan=False))["energy_bounds"]["1-2"]
    assert report["LS"]["energy_kj"] is None and report["LS"]["failure"] == reason
    assert report["CP"]["energy_kj"] == steady.energy / KILOJOULE
    assert report["CP"]["failure"] is None
    withheld, printed = [
        row for row in study_table(energetic).splitlines() if "energy bound" in row
    ]
    assert withheld.endswith(f"no bound: {reason}")
    assert f"{moved.energy / KILOJOULE:.2f}" not in withheld
    assert printed.endswith(f"{steady.energy / KILOJOULE:.2f}")
    runs = [run for run in energetic.runs if run.segment == "1-2" and "hydraulics" in run.summary()]
    assert runs and all(set(energetic.above_energy_bound(run)) == {"CP"} for run in runs)
    failures = {"energy bound CP/1-2": "no path keeps every limit"}
    raised = dataclasses.replace(
        energetic, energy_bounds={"1-2": {"LS": steady}}, bound_failures=failures
    )
    ls, cp = [row for row in study_table(raised).splitlines() if "energy bound" in row]
    assert ls.endswith(f"{steady.energy / KILOJOULE:.2f}")
    assert cp.endswith("no bound: no path keeps every limit")
    report = json.loads(json.dumps(raised.report(), allow_nan=False))["energy_bounds"]["1-2"]
    assert report["CP"] == {  # in the report too, where the page reads it
        "energy_kj": None,
        "change": None,
        "converged": False,
        "grids": [],
        "start": None,
        "failure": "no path keeps every limit",
    }


def test_every_reported_motion_is_a_csv_that_reads_back_to_its_arrays(study, tmp_path):
    """One file per best motion and per cycle strategy; every column equals the motion's array
    it names, the pump's flow is the cylinders' sum and its power p_P Q_P."""
    import pandas as pd

    from redundancy.model.hydraulics import BAR, LITRES_PER_MINUTE
    from redundancy.viz.series import write_series

    motions = {f"motion_{o}_{s}.csv": m for (o, s), m in study.best_motions.items()}
    motions |= {f"motion_cycle_{n}.csv": m for n, m in study.cycle_study.firsts.items()}
    paths = write_series(study, tmp_path)
    assert sorted(p.name for p in paths) == sorted(motions)
    # every segment has a best start for the velocity objective; the cycle two strategies
    assert {f"motion_velocity_{s}.csv" for s in SEGMENTS} <= set(motions)
    assert {"motion_cycle_free.csv", "motion_cycle_periodic.csv"} <= set(motions)
    circuit = study.robot.circuit()
    for path in paths:
        motion, table = motions[path.name], pd.read_csv(path)
        flows = motion.flows
        np.testing.assert_array_equal(table["t (s)"], motion.t[0])
        for a, name in enumerate(study.robot.actuators.names):
            for column, values in (
                (f"x_{name} (m)", motion.x),
                (f"x_dot_{name} (m/s)", motion.x_dot),
                (f"x_ddot_{name} (m/s²)", motion.x_ddot),
                (f"F_{name} (N)", motion.forces),
            ):
                np.testing.assert_array_equal(table[column], values[0, :, a])
        for c, name in enumerate(circuit.names):
            np.testing.assert_array_equal(table[f"p_L_{name} (bar)"], flows.load[0, :, c] / BAR)
            np.testing.assert_array_equal(
                table[f"Q_{name} (L/min)"], flows.flow[0, :, c] / LITRES_PER_MINUTE
            )
        cylinders = table[[f"Q_{name} (L/min)" for name in circuit.names]].sum(axis=1)
        np.testing.assert_allclose(table["Q_pump (L/min)"], cylinders, rtol=1e-12, atol=1e-12)
        pressure = flows.pump_pressure(circuit.supply)[0]
        pump_flow = table["Q_pump (L/min)"] * LITRES_PER_MINUTE
        np.testing.assert_allclose(
            table["pump_power_LS (kW)"] * 1e3, pressure * pump_flow, rtol=1e-12
        )
