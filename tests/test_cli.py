"""The console: --version, help with defaults and an example, no progress frames in a log, and
one line (never a traceback) where the output streams are odd."""

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from commands import run_cli

from redundancy.cli import parser

COMMANDS = ["robots", "describe", "check", "study", "play", "map", "cycle"]


def test_version_names_the_package_version():
    from importlib.metadata import version

    run = run_cli("--version")
    assert run.returncode == 0 and run.stdout == f"redundancy {version('redundancy')}\n"


@pytest.mark.parametrize("command", COMMANDS)
def test_help_shows_defaults_and_an_example(command, capsys):
    with pytest.raises(SystemExit) as ended:
        parser().parse_args([command, "--help"])
    assert ended.value.code == 0
    shown = capsys.readouterr().out
    assert f"example:\n  redundancy {command}" in shown
    if command in ("study", "cycle"):
        assert "(default: 100)" in shown  # --samples
        assert "(default: None)" not in shown


def test_every_option_says_what_it_does():
    """play's and cycle's --objective had no help: every option of every command has some,
    and --objective the same words wherever it is."""
    found = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))
    options = [(name, a) for name, command in found.choices.items() for a in command._actions]
    assert [f"{name} {a.option_strings}" for name, a in options if not a.help] == []
    minimise = {name: a.help for name, a in options if "--objective" in a.option_strings}
    assert sorted(minimise) == ["cycle", "play", "study"]
    assert minimise["play"] == minimise["cycle"] and minimise["study"].startswith(minimise["play"])


def test_a_run_into_a_log_draws_no_progress_frames(tmp_path):
    """Progress bars are drawn on a terminal only: a log gets lines, never '\\r' frames."""
    run = run_cli(
        "study", "--objective", "velocity", "--cycles", "0", "--samples", "3", "--out",
        str(tmp_path / "out"),
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "\r" not in run.stdout + run.stderr


def test_a_console_that_cannot_show_the_units_still_gets_the_run(tmp_path):
    """PYTHONIOENCODING=ascii: the characters it lacks (°, ±) are shown as "?"."""
    run = subprocess.run(
        [sys.executable, "-m", "redundancy", "describe"],
        capture_output=True,
        env={**os.environ, "PYTHONIOENCODING": "ascii"},
    )
    assert run.returncode == 0, run.stderr
    assert b"M_H (kg)" in run.stdout and not run.stderr


def test_describe_gives_a_rotary_actuator_s_units(capsys):
    """The slewing crane's slew is an angle: its entries of M_H are kg·m (with a length) and
    kg·m² (its own), its force a torque, N·m; the crane's, all lengths, stay kg."""
    from redundancy.cli import main

    assert main(["describe", "--robot", "hiab031_slewing"]) == 0
    out = capsys.readouterr().out
    assert "M_H (kg; kg·m in a row or column of slew, kg·m² in both) =" in out
    assert "F_H holding still (N; N·m for slew) = [    0.     18433.9429" in out
    assert main(["describe"]) == 0
    assert "M_H (kg) =" in capsys.readouterr().out
    # an arm of joints driven directly: every entry kg·m², every force a torque
    assert main(["describe", "--robot", "panda"]) == 0
    out = capsys.readouterr().out
    assert "M_H (kg·m²) =" in out and "F_H holding still (N·m) = [" in out and "-0. " not in out


def test_describe_describes_a_robot_whose_task_is_broken(tmp_path, capsys):
    """describe reads the robot's task only for a tool angle among its coordinates: a task
    file it cannot read is noted, and the robot described all the same."""
    from redundancy.cli import main

    crane = Path(__file__).parents[1] / "redundancy" / "robots" / "hiab031"
    shutil.copy(crane / "hiab031.urdf", tmp_path)
    (tmp_path / "robot.toml").write_text(
        'urdf = "hiab031.urdf"\ntool_frame = "tool"\ntask_axes = "xz"\ntask = "task.toml"\n'
    )
    (tmp_path / "task.toml").write_text("speed = 0.5\nsegments = ['a-b']\n[points]\na = [3, 0]\n")
    assert main(["describe", "--robot", str(tmp_path / "robot.toml")]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"{tmp_path.name}: n = 3 joints, task = tool xz (m = 2)")
    assert err.startswith("redundancy: note: its task is not read, ") and "'a-b'" in err


def test_the_list_of_robots_names_their_actuators_without_notes():
    """Listing the bundled robots loads each; the Panda's joints driven directly are its
    actuators in the list, not a note on standard error."""
    run = run_cli("robots", timeout=300)
    assert run.returncode == 0, run.stderr
    assert "panda_joint1, panda_joint2" in run.stdout
    assert "hiab031          n = 3, m = 2" in run.stdout
    assert run.stderr == ""


def test_a_closed_standard_output_is_one_line():
    run = subprocess.run(
        [sys.executable, "-m", "redundancy", "robots"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: os.close(1),
    )
    assert run.returncode == 2
    assert (
        run.stderr == "redundancy: error: standard output is closed; give it a file or /dev/null\n"
    )
