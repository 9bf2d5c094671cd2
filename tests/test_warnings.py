"""No numpy warning reaches the user: a study on an arm whose boom and stick are driven
directly, with no stroke, prints its results and no "note:" line."""

from pathlib import Path

from commands import run_cli

UNBOUNDED = Path(__file__).parent / "data" / "unbounded" / "robot.toml"


def test_a_study_with_unbounded_strokes_warns_of_nothing(tmp_path):
    """An unbounded stroke has no term of its own in the bound's constraints: no division by
    its infinite span (once numpy's "invalid value encountered in divide", shown as a note)."""
    options = ["--samples", "5", "--cycles", "2", "--out", str(tmp_path), "--quiet"]
    run = run_cli("study", "--robot", str(UNBOUNDED), *options)
    assert run.returncode == 0, run.stderr
    assert "bound" in run.stdout
    assert "note:" not in run.stderr and "invalid value" not in run.stderr, run.stderr
