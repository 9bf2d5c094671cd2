"""All-or-nothing output: interrupted, failed and concurrent runs leave one complete output."""

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
import weakref
from pathlib import Path

import pytest
from commands import run_cli

from redundancy.errors import InvalidInputError
from redundancy.study.output import MARKER, OutputFolder, writable

STUDY = ("study", "--objective", "velocity", "--cycles", "0", "--samples", "3", "--quiet")


def _contents(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` by relative path, with its SHA-256."""
    return {
        str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


@pytest.fixture(scope="module")
def earlier(tmp_path_factory):
    """A complete output folder of an earlier run, and its contents."""
    folder = tmp_path_factory.mktemp("earlier") / "out"
    run = run_cli(*STUDY, "--out", str(folder))
    assert run.returncode == 0, run.stderr
    return folder, _contents(folder)


def test_a_committed_folder_replaces_the_old_one_whole(tmp_path):
    target = tmp_path / "out"
    with OutputFolder(target) as out:
        (out / "report.json").write_text("1")
    with OutputFolder(target) as out:
        (out / "fig.png").write_text("2")
    assert sorted(p.name for p in target.iterdir()) == sorted([MARKER, "fig.png"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_failed_run_leaves_the_old_folder_and_no_staging(tmp_path):
    target = tmp_path / "out"
    with OutputFolder(target) as out:
        (out / "report.json").write_text("old")
    before = _contents(target)
    with pytest.raises(RuntimeError), OutputFolder(target) as out:
        (out / "report.json").write_text("new")
        raise RuntimeError("the figures failed")
    assert _contents(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with pytest.raises(RuntimeError), OutputFolder(tmp_path / "new" / "deep" / "out") as out:
        out.beside(tmp_path / "other" / "report.json", "--json").write_text("new")
        raise RuntimeError("the figures failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # the folders made, gone


def test_a_folder_of_other_files_is_refused_not_replaced(tmp_path):
    (tmp_path / "thesis.tex").write_text("mine")
    with pytest.raises(InvalidInputError, match=r"holds files this toolkit did not write"):
        OutputFolder(tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(InvalidInputError, match=r"--out .*file is a file; give a folder"):
        OutputFolder(tmp_path / "file")
    with pytest.raises(InvalidInputError, match=r"--json .*file is a file, not a folder"):
        writable(tmp_path / "file" / "report.json", "--json")
    assert (tmp_path / "thesis.tex").read_text() == "mine"


def test_unwritable_paths_fail_before_any_computing(tmp_path):
    blocker = tmp_path / "plain"
    blocker.write_text("")
    for option in ("--out", "--json"):
        path = blocker / "below" / ("report.json" if option == "--json" else "out")
        start = time.monotonic()
        run = run_cli("study", option, str(path))
        assert run.returncode == 2 and "Traceback" not in run.stderr
        assert run.stderr.count("\n") == 1
        assert f"{option} {path}: {blocker} is a file, not a folder" in run.stderr
        assert time.monotonic() - start < 3.0  # no study was run
    run = run_cli("play", "--html", str(blocker / "page.html" / "x"))
    assert run.returncode == 2 and "--html" in run.stderr and run.stderr.count("\n") == 1


def test_devices_and_pipes_are_refused_and_links_followed(tmp_path):
    """A rename would replace a device or a pipe: refused. A link stays a link, and the file or
    folder it names (even one still to be made) is written."""
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    with pytest.raises(InvalidInputError, match=r"--json .*pipe is not a regular file"):
        writable(pipe, "--json")
    with pytest.raises(InvalidInputError, match=r"--json .*null is not a regular file"):
        OutputFolder(tmp_path / "out").beside(Path(os.devnull), "--json")
    assert pipe.is_fifo() and Path(os.devnull).is_char_device()
    (tmp_path / "folder").symlink_to("made-later")
    (tmp_path / "report").symlink_to("kept.json")
    with OutputFolder(tmp_path / "folder") as out:
        (out / "report.json").write_text("1")
        out.beside(tmp_path / "report", "--json").write_text("2")
    assert (tmp_path / "folder").is_symlink() and (tmp_path / "report").is_symlink()
    assert (tmp_path / "made-later" / "report.json").read_text() == "1"
    assert (tmp_path / "kept.json").read_text() == "2"


@pytest.mark.parametrize(
    ("json", "out"),
    [("out", "out"), ("out/report.json", "out"), ("x", "x/out")],
    ids=["same", "inside", "holds"],
)
def test_a_report_overlapping_the_output_folder_is_refused_before_any_computing(
    tmp_path, json, out
):
    start = time.monotonic()
    run = run_cli(*STUDY, "--out", out, "--json", json, cwd=tmp_path)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert f"--json {json} overlaps --out {out}" in run.stderr
    assert time.monotonic() - start < 3.0  # no study was run
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_goes_away_stops_nothing(tmp_path):
    """stdout piped into a reader that has gone (``| head -1``): the run still ends well, its
    output written, and says nothing about the pipe."""
    for command in (["robots"], [*STUDY, "--out", str(tmp_path / "out")]):
        read, write = os.pipe()
        os.close(read)  # the reader is gone before the first line
        process = subprocess.run(
            [sys.executable, "-m", "redundancy.cli", *command],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
        )
        os.close(write)
        said = [line for line in process.stderr.splitlines() if "redundancy: note:" not in line]
        assert process.returncode == 0 and said == [], process.stderr
    assert json.loads((tmp_path / "out" / "report.json").read_text())["studies"]


def _foreground() -> None:
    """In the child: SIGINT as a foreground job has it, even where this test runs as a
    background job (which ignores SIGINT, and so, rightly, would its children)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "terminate"])
def test_a_signal_while_the_libraries_load_ends_the_command_with_one_line(tmp_path, stop):
    """The command handles Ctrl-C and SIGTERM from its first moment: while it still imports
    numpy, Pinocchio and the rest (about half a second), they end it with one line, nothing
    written."""
    for delay in (0.1, 0.2, 0.3):
        process = subprocess.Popen(
            [sys.executable, "-m", "redundancy", *STUDY, "--out", str(tmp_path / "out")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_foreground,
        )
        time.sleep(delay)
        process.send_signal(stop)
        _, stderr = process.communicate(timeout=60)
        ending = "terminated" if stop == signal.SIGTERM else "interrupted"
        assert stderr.splitlines() == [f"redundancy: {ending}"], (delay, stderr)
        assert process.returncode == (143 if stop == signal.SIGTERM else 130)
        assert list(tmp_path.iterdir()) == []


def test_a_signal_python_had_to_ignore_still_ends_the_command(monkeypatch, capsys):
    """A Ctrl-C whose KeyboardInterrupt is raised inside a weakref callback, where Python can
    only report and ignore it: no report, and the command ends with one line and status 130."""
    from redundancy import cli

    def run(args):
        class Part:
            pass

        part = Part()
        noted = weakref.ref(part, lambda _: cli._interrupt(signal.SIGINT, None))
        del part  # the callback runs here, and raises
        assert noted() is None
        print("finished")

    monkeypatch.setattr(cli, "_robots_command", run)
    assert cli.main(["robots"]) == 130
    captured = capsys.readouterr()
    assert captured.err.splitlines() == ["redundancy: interrupted"], captured.err


def _staged_files(parent: Path) -> int:
    return sum(
        len(list(folder.iterdir())) for folder in parent.glob(".out.partial-*") if folder.is_dir()
    )


@pytest.mark.parametrize(
    ("stop", "staged", "status"),
    [(signal.SIGINT, 2, 130), (signal.SIGTERM, 2, 143), (signal.SIGTERM, 5, 143)],
    ids=["ctrl-c, first file", "terminate, first file", "terminate, later"],
)
def test_an_interrupted_write_leaves_the_earlier_output_byte_identical(
    earlier, stop, staged, status
):
    """The signal lands once the run has staged ``staged`` files (the marker, then its report
    and figures): the earlier folder stays byte-identical, nothing temporary remains."""
    folder, contents = earlier
    command = [sys.executable, "-m", "redundancy.cli", *STUDY, "--out", str(folder)]
    run = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_foreground,
    )
    deadline = time.monotonic() + 60
    while _staged_files(folder.parent) < staged and run.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.005)
    if run.poll() is not None:
        pytest.fail(f"the run ended before {staged} files were staged: {run.stderr.read()}")
    os.kill(run.pid, stop)
    _, errors = run.communicate(timeout=30)
    assert run.returncode == status, errors
    assert errors.count("\n") == 1 and "Traceback" not in errors
    assert _contents(folder) == contents
    assert sorted(p.name for p in folder.parent.iterdir()) == ["out"]


def test_two_runs_into_one_folder_leave_one_complete_output(tmp_path):
    folder = tmp_path / "out"
    command = [sys.executable, "-m", "redundancy.cli", *STUDY[:-2]]
    runs = [
        subprocess.Popen(
            [*command, samples, "--quiet", "--out", str(folder)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for samples in ("3", "4")
    ]
    for run in runs:
        run.communicate(timeout=120)
        assert run.returncode == 0
    report = json.loads((folder / "report.json").read_text())
    assert report["samples"] in (3, 4)
    names = sorted(p.name for p in folder.iterdir())
    assert MARKER in names and "fig4a_peak_velocity.png" in names and "report.json" in names
    assert len(names) == len(set(names)) and not any(n.startswith(".out") for n in names)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_signals_during_the_swap_wait_for_its_end():
    """A Ctrl-C that arrives inside the swap is handled after it, as the Ctrl-C it was."""
    from redundancy.study.output import _deferred_signals

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in the foreground
    try:
        with pytest.raises(KeyboardInterrupt), _deferred_signals():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            finished = True  # not interrupted inside the block
    finally:
        signal.signal(signal.SIGINT, previous)
    assert finished


def test_a_failed_swap_puts_the_old_folder_back(tmp_path, monkeypatch):
    target = tmp_path / "out"
    with OutputFolder(target) as out:
        (out / "report.json").write_text("old")
    before = _contents(target)
    replace = os.replace

    def failing(source, destination):
        if ".partial-" in str(source):
            raise OSError(28, "No space left on device")
        replace(source, destination)

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(OSError), OutputFolder(target) as out:
        (out / "report.json").write_text("new")
    assert _contents(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_files_saved_into_the_target_while_a_run_computes_are_kept(tmp_path):
    target = tmp_path / "out"
    with OutputFolder(target) as out:
        (out / "report.json").write_text("old")
    run = OutputFolder(target)
    (target / "notes.txt").write_text("mine")
    with pytest.raises(InvalidInputError, match=r"holds files this toolkit did not write"), run:
        (run / "report.json").write_text("new")
    assert (target / "notes.txt").read_text() == "mine"
    assert (target / "report.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_current_folder_is_not_an_output_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in (".", ".."):
        with pytest.raises(InvalidInputError, match="give a folder by its own name"):
            OutputFolder(name)
