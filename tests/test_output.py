"""All-or-nothing output: interrupted, killed, failed and concurrent runs leave one complete
output, and nothing the toolkit did not write is lost."""

import errno
import hashlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
import warnings
import weakref
from pathlib import Path

import pytest
from commands import as_foreground, run_cli

from redundancy.errors import InvalidInputError
from redundancy.model.loading import bundled_root
from redundancy.study import output
from redundancy.study.output import MARKER, OutputFolder, _manifest, writable
from redundancy.study.signals import deferred

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


def test_a_signal_after_the_commit_says_the_output_was_written(tmp_path):
    """A signal while the command lists what it wrote used to say only "interrupted", status
    130, as if the earlier folder were kept, where the new one had replaced it whole: the line
    now says so. Before any commit it says what it always said."""
    from redundancy.study.signals import announce, caught

    target = tmp_path / "out"
    lines: list[str] = []
    with caught():
        assert announce(signal.SIGINT, lines.append) == 130
    with caught():
        with OutputFolder(target) as out:
            (out / "report.json").write_text("1")
        assert announce(signal.SIGTERM, lines.append) == 143
    assert lines == [
        "redundancy: interrupted\n",
        f"redundancy: terminated after writing {target} whole\n",
    ]


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
    with pytest.raises(InvalidInputError, match=r"^--out /dev/null is a device, a pipe or a soc"):
        OutputFolder("/dev/null")
    with pytest.raises(InvalidInputError, match=r"--json .*file is a file, not a folder"):
        writable(tmp_path / "file" / "report.json", "--json")
    assert (tmp_path / "thesis.tex").read_text() == "mine"


NO_ROBOT = ("--robot", "no-such-robot")  # a study that fails as soon as it loads the robot


def test_unwritable_paths_fail_before_any_computing(tmp_path):
    """The paths are checked before the robot is even loaded: the error names the path."""
    blocker = tmp_path / "plain"
    blocker.write_text("")
    for option in ("--out", "--json"):
        path = blocker / "below" / ("report.json" if option == "--json" else "out")
        run = run_cli("study", *NO_ROBOT, option, str(path))
        assert run.returncode == 2 and "Traceback" not in run.stderr
        assert run.stderr.count("\n") == 1
        assert f"{option} {path}: {blocker} is a file, not a folder" in run.stderr
    long = tmp_path / ("a" * 300)
    run = run_cli("study", *NO_ROBOT, "--out", str(long))
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "cannot write there (File name too long)" in run.stderr
    run = run_cli("study", *NO_ROBOT, "--out", "/sys/out")  # read-only, even for root
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "--out /sys/out: cannot write there" in run.stderr
    run = run_cli("play", "--html", str(blocker / "page.html" / "x"))
    assert run.returncode == 2 and "--html" in run.stderr and run.stderr.count("\n") == 1


def _as_a_user(*args: str) -> subprocess.CompletedProcess:
    """``redundancy ARGS`` run as a user without root's licence to write anywhere: where the
    suite runs as root, with the capabilities that override a folder's permissions dropped."""
    exempt = ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", "--"]
    command = [*(exempt if os.geteuid() == 0 else []), sys.executable, "-m", "redundancy", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=600)


def test_a_read_only_earlier_output_is_refused_before_any_computing_and_kept(tmp_path):
    """The output replaces an earlier output folder whole and removes the files it replaces:
    where that folder is read-only, the command says so at once, before it loads the robot,
    and leaves the folder as it was, with nothing beside it."""
    target = tmp_path / "out"
    _earlier_output(target)
    before = _contents(target)
    target.chmod(0o555)
    try:
        run = _as_a_user("study", *NO_ROBOT, "--out", str(target))
    finally:
        target.chmod(0o755)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert f"--out {target}: cannot write there (the folder is not writable" in run.stderr
    assert _contents(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


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


def test_a_file_written_whole_never_replaces_a_device_a_pipe_or_a_folder(tmp_path):
    """What writes one file whole (`write_atomically`: an exported playback, a figure) refuses,
    in one line, a path it would replace by a rename that is not a regular file, and one it
    cannot write; nothing is left beside them. A regular file is replaced."""
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    write = lambda path: path.write_text("page")  # noqa: E731
    for path, why in (
        (pipe, "is not a regular file"),  # as a device is: never the real one, in a test
        (tmp_path, "is a folder"),
        (Path("/proc/page.html"), "cannot write there"),
        (pipe / "page.html", "is a file, not a folder"),
        (tmp_path / f"{'a' * 300}.html", "cannot write there"),  # a name longer than 255 bytes
    ):
        with pytest.raises(InvalidInputError, match=f"^output {path}.* {why}"):
            output.write_atomically(path, write)
    assert pipe.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]
    (tmp_path / "page.html").write_text("old")
    output.write_atomically(tmp_path / "page.html", write)
    assert (tmp_path / "page.html").read_text() == "page"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html", "pipe"]


@pytest.mark.parametrize(
    ("json", "out"),
    [("out", "out"), ("out/report.json", "out"), ("x", "x/out")],
    ids=["same", "inside", "holds"],
)
def test_a_report_overlapping_the_output_folder_is_refused_before_any_computing(
    tmp_path, json, out
):
    run = run_cli(*STUDY, *NO_ROBOT, "--out", out, "--json", json, cwd=tmp_path)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert f"--json {json} overlaps --out {out}" in run.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_path_with_a_name_too_long_is_one_line(tmp_path):
    """A path whose name is longer than the file system allows (255 bytes) was an internal
    error, status 1; it is one line naming it, status 2, given as the robot or the report."""
    name = "b" * 300
    for arguments in (
        ("describe", "--robot", str(tmp_path / name)),
        (*STUDY, "--out", str(tmp_path / "o"), "--json", str(tmp_path / f"{name}.json")),
    ):
        run = run_cli(*arguments)
        assert run.returncode == 2, run.stderr
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].endswith(": File name too long"), lines
        assert name in lines[0]


def test_a_report_or_page_naming_an_input_file_is_refused_and_the_input_kept(tmp_path):
    """--json or --html naming a file the command reads (its task file, robot file or URDF)
    replaced it with the report: one line naming it now, exit 2, the file as it was."""
    robot = tmp_path / "crane"
    shutil.copytree(bundled_root() / "hiab031", robot)
    runs = {
        "task.toml": ("study", "--json", "task file"),
        "robot.toml": ("cycle", "--json", "robot file"),
        "hiab031.urdf": ("play", "--html", "URDF"),
    }
    for name, (command, option, what) in runs.items():
        path = robot / name
        before = path.read_bytes()
        extra = () if command == "play" else ("--samples", "3", "--out", str(tmp_path / "o"))
        run = run_cli(command, "--robot", str(robot / "robot.toml"), option, str(path), *extra)
        assert run.returncode == 2 and path.read_bytes() == before
        assert run.stderr.strip().splitlines() == [
            f"redundancy: error: {option} {path} is the {what} this command reads; give "
            "another path"
        ]


def test_a_loop_of_links_and_a_path_inside_an_earlier_output_are_refused_at_once(tmp_path):
    """An --out whose links lead round in a loop is refused before any computing (the commit's
    rename would meet it forever); --out, --json or --html inside an output folder the toolkit
    wrote would mix its files, and is refused, that folder untouched."""
    (tmp_path / "a").symlink_to("b")
    (tmp_path / "b").symlink_to("a")
    run = run_cli("study", *NO_ROBOT, "--out", str(tmp_path / "a"))
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "--out " + str(tmp_path / "a") + ": cannot write there (Too many levels" in run.stderr
    with OutputFolder(tmp_path / "earlier") as out:
        (out / "report.json").write_text("{}")
    before = sorted((p.name, p.read_bytes()) for p in (tmp_path / "earlier").iterdir())
    for option, path in (("--out", "earlier/sub"), ("--json", "earlier/report.json")):
        run = run_cli("study", *NO_ROBOT, "--out", "new", option, path, cwd=tmp_path)
        assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
        assert f"{option} {path} lies in {tmp_path / 'earlier'}, an output folder" in run.stderr
    run = run_cli("play", "--html", "earlier/.redundancy-output", cwd=tmp_path)
    assert run.returncode == 2 and "--html earlier/.redundancy-output lies in" in run.stderr
    assert sorted((p.name, p.read_bytes()) for p in (tmp_path / "earlier").iterdir()) == before


def test_a_value_with_a_newline_or_an_escape_stays_on_one_line(tmp_path):
    run = run_cli("study", "--check", "x1\nx9\x1b[31m", "--out", str(tmp_path / "o"))
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "x1\\nx9\\x1b[31m" in run.stderr


def test_a_full_disk_is_one_line_naming_the_output(tmp_path, monkeypatch, capsys):
    """No space left while the figures are written: one line naming --out, status 2, and the
    staged output gone."""
    from redundancy.cli import main
    from redundancy.viz import plots

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(plots, "write_pngs", full)
    status = main(
        ["study", "--samples", "3", "--cycles", "0", "--quiet", "--out", str(tmp_path / "o")]
    )
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 1, lines
    said = f"{tmp_path / 'o'}: No space left on device; this run's output was not kept"
    assert lines[0] == f"redundancy: error: {said}"
    assert list(tmp_path.iterdir()) == []


def test_a_page_the_file_system_will_not_replace_is_one_line_naming_it(
    tmp_path, monkeypatch, capsys
):
    """The playback page written whole by a rename onto the path given, which the file system
    refuses (an immutable file there): one line naming that path, status 2, and no temporary
    file left beside it."""
    from redundancy.cli import main

    page, replace = tmp_path / "page.html", os.replace

    def refused(source, target):
        if Path(target) == page:
            raise PermissionError(errno.EPERM, os.strerror(errno.EPERM), source, None, target)
        replace(source, target)

    monkeypatch.setattr(output.os, "replace", refused)
    status = main(["play", "--html", str(page)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 1, lines
    assert lines[0] == f"redundancy: error: {page}: cannot write there (Operation not permitted)"
    assert list(tmp_path.iterdir()) == []


def test_an_immutable_report_or_page_is_refused_before_any_computing(tmp_path, capsys, monkeypatch):
    """A --json or --html file marked immutable (chattr +i), which no rename may replace: one
    line naming the option, before the robot is loaded, and nothing written beside it. Where
    this file system (or user) cannot mark a file, its flags' reading is told the file is."""
    from redundancy.cli import main

    kept = tmp_path / "kept.json"
    kept.write_text("old")
    assert not output._unchangeable(kept) and not output._unchangeable(tmp_path / "none")
    chattr = shutil.which("chattr")
    marked = chattr is not None and not subprocess.run([chattr, "+i", kept]).returncode
    if not marked:
        monkeypatch.setattr(output, "_unchangeable", lambda path: path == kept)
    try:
        assert output._unchangeable(kept)
        for option in ("--json", "--html"):
            command = "study" if option == "--json" else "play"
            status = main([command, *NO_ROBOT, option, str(kept)])
            lines = capsys.readouterr().err.strip().splitlines()
            assert status == 2 and len(lines) == 1, lines
            assert f"{option} {kept}: cannot write there (the file is marked immutable" in lines[0]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.json"]
        assert kept.read_text() == "old"
    finally:
        if marked:
            subprocess.run([str(chattr), "-i", kept], check=True)


def test_a_full_disk_under_the_json_report_names_that_file(tmp_path, monkeypatch, capsys):
    """No space left for --json's report, kept outside --out: the line names that file, which
    it used to blame on --out, and nothing of the run is left."""
    from redundancy import cli

    def full(path):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(
        cli, "write_report", lambda result, path: output.write_atomically(path, full)
    )
    report = tmp_path / "json" / "report.json"
    status = cli.main([*STUDY, "--out", str(tmp_path / "o"), "--json", str(report)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 1, lines
    said = f"{report}: No space left on device; this run's output was not kept"
    assert lines[0] == f"redundancy: error: {said}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")
def test_a_full_standard_output_names_it(tmp_path):
    """Standard output on a full disk (/dev/full): one line naming it, not --out, status 2,
    and no second report as the interpreter flushes it on its way out."""
    for command in (["robots"], [*STUDY, "--out", str(tmp_path / "out")]):
        with open("/dev/full", "w") as full:
            process = subprocess.run(
                [sys.executable, "-m", "redundancy", *command],
                stdout=full,
                stderr=subprocess.PIPE,
                text=True,
            )
        said = "standard output: No space left on device; this run's output was not kept"
        assert process.stderr == f"redundancy: error: {said}\n"
        assert process.returncode == 2
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_goes_away_stops_nothing(tmp_path):
    """stdout piped into a reader that has gone (``| head -1``): the run still ends well, its
    output written, and says nothing about the pipe."""
    for command in (["robots"], [*STUDY, "--out", str(tmp_path / "out")]):
        read, write = os.pipe()
        os.close(read)  # the reader is gone before the first line
        process = subprocess.run(
            [sys.executable, "-m", "redundancy", *command],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
        )
        os.close(write)
        said = [line for line in process.stderr.splitlines() if "redundancy: note:" not in line]
        assert process.returncode == 0 and said == [], process.stderr
    assert json.loads((tmp_path / "out" / "report.json").read_text())["studies"]


def handles_sigterm(pid: int) -> bool:
    """Whether the process ``pid`` has a handler of its own for SIGTERM (the command installs
    its handlers first thing, before it imports numpy, Pinocchio and the rest)."""
    status = Path(f"/proc/{pid}/status").read_text()
    caught = next(line for line in status.splitlines() if line.startswith("SigCgt:"))
    return bool(int(caught.split()[1], 16) & 1 << (signal.SIGTERM - 1))


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "terminate"])
def test_a_signal_while_the_libraries_load_ends_the_command_with_one_line(tmp_path, stop):
    """The command handles Ctrl-C and SIGTERM from its first moment: once its handler is in
    place, a signal at any instant of the imports (about a second) or of the study after them
    ends it with one line, nothing written."""
    pace = random.Random(int(stop))
    for _ in range(6):
        process = subprocess.Popen(
            [sys.executable, "-m", "redundancy", *STUDY, "--out", str(tmp_path / "out")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=as_foreground,
        )
        deadline = time.monotonic() + 600
        while not handles_sigterm(process.pid):
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.001)
        time.sleep(pace.uniform(0, 1))  # an instant of the imports, or just after them
        process.send_signal(stop)
        _, stderr = process.communicate(timeout=600)
        ending = "terminated" if stop == signal.SIGTERM else "interrupted"
        assert stderr.splitlines() == [f"redundancy: {ending}"], stderr
        assert process.returncode == (143 if stop == signal.SIGTERM else 130)
        assert list(tmp_path.iterdir()) == []


def test_a_signal_while_the_command_module_loads_its_handler_ends_it_with_one_line():
    """Ctrl-C at the first import the command's entry makes (its console script runs
    ``from redundancy.__main__ import main``), before the handler is in place: held back until
    it is, then one line and status 130, where it used to print a KeyboardInterrupt
    traceback."""
    script = """
import os, signal, sys

class Interrupt:  # Ctrl-C as the entry module imports the handler's package
    def find_spec(self, name, path, target=None):
        if name == "redundancy.study":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)

sys.meta_path.insert(0, Interrupt())
from redundancy.__main__ import main
sys.exit(main())
"""
    done = subprocess.run(
        [sys.executable, "-c", script, "robots"],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=as_foreground,
    )
    assert done.stderr == "redundancy: interrupted\n", done.stderr
    assert done.returncode == 130 and done.stdout == ""


def test_a_signal_once_the_command_has_finished_changes_nothing():
    """Ctrl-C after the command's last exit function, where the interpreter's end would put
    the default action back (which ends a process by the signal, without a word): ignored, as
    the command has finished; its output and status stand."""
    script = """
import atexit, os, signal, sys, time

def late():  # registered before the command's own, so run after them
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.5)  # where a handler would run

atexit.register(late)
sys.argv = ["redundancy", "robots"]
from redundancy.__main__ import main
sys.exit(main())
"""
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=as_foreground,
    )
    assert (done.returncode, done.stderr) == (0, "")
    assert "hiab031" in done.stdout


def test_a_signal_while_the_staging_folder_is_made_leaves_nothing(tmp_path, monkeypatch):
    """Ctrl-C between making the staging folder and marking it, before any `with` block could
    discard it: the folder is removed, and the target's parent holds nothing new."""

    def interrupted(self, files):
        raise KeyboardInterrupt

    monkeypatch.setattr(OutputFolder, "_mark", interrupted)
    with pytest.raises(KeyboardInterrupt):
        OutputFolder(tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_a_signal_python_had_to_ignore_still_ends_the_command(monkeypatch, capsys):
    """A Ctrl-C whose KeyboardInterrupt is raised inside a weakref callback, where Python can
    only report and ignore it: no report, and the command ends with one line and status 130."""
    from redundancy import cli
    from redundancy.study.signals import stop

    def run(args):
        class Part:
            pass

        part = Part()
        noted = weakref.ref(part, lambda _: stop(signal.SIGINT, None))
        del part  # the callback runs here, and raises
        assert noted() is None
        print("finished")

    monkeypatch.setattr(cli, "_robots_command", run)
    assert cli.main(["robots"]) == 130
    captured = capsys.readouterr()
    assert captured.err.splitlines() == ["redundancy: interrupted"], captured.err


def test_a_second_signal_while_the_command_ends_adds_no_second_line():
    """Ctrl-C twice: the second arrives once the command has written that it is interrupted,
    and ends the process at once with the same status, saying nothing more."""
    script = """
import os, signal, sys
from redundancy import cli
from redundancy.study import signals

class Stderr:  # the second Ctrl-C right after the command's line
    def write(self, text):
        sys.__stderr__.write(text)
        sys.__stderr__.flush()
        os.kill(os.getpid(), signal.SIGINT)

    def reconfigure(self, **options):
        pass

    def flush(self):
        pass

def run(args):
    raise KeyboardInterrupt

signals.install()
cli._robots_command = run
sys.stderr = Stderr()
sys.exit(cli.main(["robots"]))
"""
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600
    )
    assert done.stderr == "redundancy: interrupted\n", done.stderr
    assert done.returncode == 130


def test_a_signal_a_library_swallowed_stops_the_commit(tmp_path):
    """A Ctrl-C whose KeyboardInterrupt a weakref callback swallowed while the output was
    staged: the commit raises it instead of writing, and nothing is left."""
    from redundancy.study.signals import caught, stop

    class Part:
        pass

    with caught(), pytest.raises(KeyboardInterrupt), OutputFolder(tmp_path / "out") as out:
        (out / "report.json").write_text("{}")
        part = Part()
        noted = weakref.ref(part, lambda _: stop(signal.SIGINT, None))
        del part  # the callback runs here; its KeyboardInterrupt is ignored
        assert noted() is None
    assert list(tmp_path.iterdir()) == []


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
    and figures): the earlier folder stays byte-identical, nothing temporary remains. (The run
    is held still while the test looks whether it has begun its commit, which a loaded machine
    may let it reach first: then the signal waits for the commit's end, and the new output is
    there, complete.)"""
    folder, contents = earlier
    command = [sys.executable, "-m", "redundancy", *STUDY, "--out", str(folder)]
    run = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=as_foreground,
    )
    deadline = time.monotonic() + 600
    while _staged_files(folder.parent) < staged and run.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.005)
    if run.poll() is not None:
        pytest.fail(f"the run ended before {staged} files were staged: {run.stderr.read()}")
    os.kill(run.pid, signal.SIGSTOP)
    staging = list(folder.parent.glob(".out.partial-*"))
    committing = not staging or any((_manifest(f) or {"files": None})["files"] for f in staging)
    os.kill(run.pid, stop)
    os.kill(run.pid, signal.SIGCONT)
    _, errors = run.communicate(timeout=600)
    assert run.returncode == status, errors
    assert errors.count("\n") == 1 and "Traceback" not in errors
    if committing:
        assert _contents(folder).keys() == contents.keys()
        contents.update(_contents(folder))  # the earlier output from now on
    else:
        assert _contents(folder) == contents
    assert sorted(p.name for p in folder.parent.iterdir()) == ["out"]


def test_two_runs_into_one_folder_leave_one_complete_output(tmp_path):
    folder = tmp_path / "out"
    command = [sys.executable, "-m", "redundancy", *STUDY[:-2]]
    runs = [
        subprocess.Popen(
            [*command, samples, "--quiet", "--out", str(folder)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for samples in ("3", "4")
    ]
    for run in runs:
        run.communicate(timeout=600)
        assert run.returncode == 0
    report = json.loads((folder / "report.json").read_text())
    assert report["samples"] in (3, 4)
    names = sorted(p.name for p in folder.iterdir())
    assert MARKER in names and "fig4a_peak_velocity.png" in names and "report.json" in names
    assert len(names) == len(set(names)) and not any(n.startswith(".out") for n in names)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_signals_during_the_swap_wait_for_its_end():
    """A Ctrl-C that arrives inside the swap is handled after it, as the Ctrl-C it was."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in the foreground
    try:
        with pytest.raises(KeyboardInterrupt), deferred():
            signal.raise_signal(signal.SIGINT)  # in this thread: handled before the next line
            finished = True  # not interrupted inside the block
    finally:
        signal.signal(signal.SIGINT, previous)
    assert finished


def test_a_failed_swap_leaves_the_old_folder(tmp_path, monkeypatch):
    """The exchange is one rename: where it fails (a full disk), nothing has moved."""
    target = tmp_path / "out"
    with OutputFolder(target) as out:
        (out / "report.json").write_text("old")
    before = _contents(target)
    rename = output._rename

    def failing(source, destination, flags):
        if flags == output.RENAME_EXCHANGE:
            raise OSError(28, "No space left on device")
        rename(source, destination, flags)

    monkeypatch.setattr(output, "_rename", failing)
    with (
        pytest.raises(InvalidInputError, match=r"cannot write there \(No space left"),
        OutputFolder(target) as out,
    ):
        (out / "report.json").write_text("new")
    assert _contents(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def _earlier_output(target: Path) -> None:
    with OutputFolder(target) as out:
        (out / "report.json").write_text("old")
        (out / "fig.png").write_text("old")


def test_files_saved_into_an_earlier_output_are_kept_and_named(tmp_path):
    """A user's notes and a folder named like a figure, saved into an earlier output, before
    the run or while it computes: carried into the new output, with one line naming them."""
    target = tmp_path / "out"
    _earlier_output(target)
    (target / "notes.html").write_text("mine")
    (target / "old_runs.png").mkdir()
    (target / "old_runs.png" / "a.png").write_text("mine too")
    run = OutputFolder(target)
    (target / "later.txt").write_text("saved while it computed")
    with pytest.warns(UserWarning, match=r"kept later.txt, notes.html, old_runs.png, which"), run:
        (run / "report.json").write_text("new")
    assert (target / "notes.html").read_text() == "mine"
    assert (target / "old_runs.png" / "a.png").read_text() == "mine too"
    assert (target / "later.txt").read_text() == "saved while it computed"
    assert (target / "report.json").read_text() == "new"
    assert not (target / "fig.png").exists()  # the earlier output's, not written again
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_folder_of_pictures_is_refused_and_kept(tmp_path):
    pictures = tmp_path / "holiday"
    pictures.mkdir()
    (pictures / "beach.png").write_bytes(b"\x89PNG mine")
    run = run_cli(*STUDY, "--out", str(pictures))
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "holds files this toolkit did not write (beach.png)" in run.stderr
    assert _contents(pictures) == {"beach.png": hashlib.sha256(b"\x89PNG mine").hexdigest()}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["holiday"]
    for name in ("dune.png", "sea.png", "sun.png"):  # more than it lists: how many more
        (pictures / name).write_bytes(b"mine")
    run = run_cli(*STUDY, "--out", str(pictures))
    assert "did not write (beach.png, dune.png, sea.png and 1 more); give" in run.stderr


def test_a_file_of_the_outputs_name_not_in_its_manifest_is_not_replaced(tmp_path):
    target = tmp_path / "out"
    _earlier_output(target)
    (target / "summary.json").write_text("mine")
    with (
        pytest.raises(InvalidInputError, match=r"holds summary.json, which this toolkit did"),
        OutputFolder(target) as out,
    ):
        (out / "summary.json").write_text("new")
    assert (target / "summary.json").read_text() == "mine"
    assert (target / "report.json").read_text() == "old"


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_a_path_that_appears_at_the_target_during_the_run_is_left_as_it_is(tmp_path, kind):
    target = tmp_path / "out"
    run = OutputFolder(target)
    if kind == "file":
        target.write_text("mine")
    else:
        target.mkdir()
        (target / "mine.png").write_text("mine")
    with pytest.raises(InvalidInputError, match=r"is a file; give a folder|did not write"), run:
        (run / "report.json").write_text("new")
    mine = target if kind == "file" else target / "mine.png"
    assert mine.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_new_run_removes_the_staging_folders_of_dead_runs_and_says_so(tmp_path):
    target = tmp_path / "out"
    _earlier_output(target)
    dead = tmp_path / f".out.partial-{_dead_pid()}-abc"
    dead.mkdir()
    (dead / "report.json").write_text("half")
    alive = tmp_path / f".out.partial-{os.getppid()}-abc"  # a run still computing
    alive.mkdir()
    with (
        pytest.warns(UserWarning, match=rf"removed {dead.name}: staged by runs that were"),
        OutputFolder(target) as out,
    ):
        (out / "report.json").write_text("new")
    assert sorted(p.name for p in tmp_path.iterdir()) == [alive.name, "out"]


def _refusing_unlink(monkeypatch, refused) -> None:
    """Removing a file for which ``refused(path)`` holds fails as an immutable file's does."""
    unlink = Path.unlink

    def refusing(path, missing_ok=False):
        if refused(path):
            raise PermissionError(errno.EPERM, os.strerror(errno.EPERM), str(path))
        unlink(path, missing_ok=missing_ok)

    monkeypatch.setattr(Path, "unlink", refusing)


def test_an_earlier_output_that_cannot_be_removed_is_named_and_the_new_one_kept(
    tmp_path, monkeypatch
):
    """Once the new output has taken the folder's place, a file of the earlier one the file
    system will not remove leaves that folder beside it, named in a note: the run is done, its
    output whole, and no error says otherwise."""
    target = tmp_path / "out"
    _earlier_output(target)
    _refusing_unlink(monkeypatch, lambda path: path.parent.name.startswith(".out.partial-"))
    with (
        pytest.warns(UserWarning, match=r"could not remove this earlier output \(Operation"),
        OutputFolder(target) as out,
    ):
        (out / "report.json").write_text("new")
    assert (target / "report.json").read_text() == "new"
    (left,) = (p for p in tmp_path.iterdir() if p.name.startswith(".out.partial-"))
    assert (left / "report.json").read_text() == "old"


def test_a_dead_runs_folder_that_cannot_be_removed_does_not_block_the_next_run(
    tmp_path, monkeypatch
):
    """A dead run's staging folder holding an earlier output the file system will not remove
    is named in a note, left where it is, and the run goes on: it does not fail every later run
    into the same folder."""
    target = tmp_path / "out"
    _earlier_output(target)
    dead = tmp_path / f".out.partial-{_dead_pid()}-abc"
    shutil.copytree(target, dead)
    _refusing_unlink(monkeypatch, lambda path: path == dead / "report.json")
    for version in ("new", "newer"):
        with warnings.catch_warnings(record=True) as notes:
            warnings.simplefilter("always")
            with OutputFolder(target) as out:
                (out / "report.json").write_text(version)
        (note,) = (str(n.message) for n in notes)  # not "removed": it is still there
        assert note.startswith(f"{dead}: could not remove this earlier output (Operation")
        assert (target / "report.json").read_text() == version
    assert (dead / "report.json").read_text() == "old"


CHURN = """
import sys
from pathlib import Path
from redundancy.study.output import OutputFolder

target, report = Path(sys.argv[1]), Path(sys.argv[2])
print("ready", flush=True)
for version in range(1, 1_000_000):
    with OutputFolder(target) as out:
        for name in ("fig.png", "page.html", "report.json"):
            (out / name).write_text(str(version))
        out.beside(report, "--json").write_text(str(version))
"""


def test_killed_at_any_instant_of_its_writing_a_run_leaves_the_old_or_the_new_output(tmp_path):
    """A process that does nothing but commit outputs, version after version, is killed
    (SIGKILL) at 50 random instants. Each time the folder holds one complete version and the
    user's notes; once the next run has looked (finishing a --json the killed one had staged,
    removing its staging folder), the --json file holds the folder's version, the notes are
    there, and nothing else is left."""
    target, report = tmp_path / "out", tmp_path / "report.json"
    with OutputFolder(target) as out:
        for name in ("fig.png", "page.html", "report.json"):
            (out / name).write_text("0")
        out.beside(report, "--json").write_text("0")
    (target / "notes.html").write_text("mine")
    pace = random.Random(50)
    for _ in range(50):
        churn = subprocess.Popen(
            [sys.executable, "-c", CHURN, str(target), str(report)],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert churn.stdout.readline() == "ready\n"  # type: ignore[union-attr]
        time.sleep(pace.uniform(0, 0.3))
        churn.kill()
        churn.wait(timeout=600)
        names = {p.name for p in target.iterdir()} - {"notes.html"}
        assert names == {MARKER, "fig.png", "page.html", "report.json"}
        versions = {(target / name).read_text() for name in names - {MARKER}}
        assert len(versions) == 1  # one complete version
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the next run's notes
            OutputFolder(target).discard()  # the next run, stopped at once
        assert report.read_text() == versions.pop()
        assert (target / "notes.html").read_text() == "mine"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "report.json"]


def test_a_bind_mount_as_the_output_folder_is_refused_before_any_work(tmp_path, monkeypatch):
    """A bind mount on the same device (a container's volume) is a mount point that only the
    kernel's mount table lists: refused as the folder is named, its name read with the
    table's octal escapes; a folder beside it is not."""
    volume, beside = tmp_path / "my volume", tmp_path / "beside"
    volume.mkdir()
    table = tmp_path / "mountinfo"
    escaped = str(volume).replace(" ", "\\040")
    table.write_text(
        "22 1 8:1 / / rw,relatime shared:1 - ext4 /dev/sda1 rw\n"
        f"97 22 8:1 /srv/data {escaped} rw,relatime shared:1 - ext4 /dev/sda1 rw\n"
    )
    monkeypatch.setattr(output, "MOUNTS", table)
    with pytest.raises(InvalidInputError, match=f"^--out {volume} is a mount point: "):
        OutputFolder(volume)
    assert sorted(p.name for p in volume.iterdir()) == []
    OutputFolder(beside).discard()


@pytest.mark.skipif(not os.path.ismount("/proc"), reason="/proc is no mount point here")
def test_a_mount_point_as_the_output_folder_is_refused_before_any_work(tmp_path):
    """A mount point cannot be exchanged with the staged folder (the rename fails, EBUSY): it
    is refused as the folder is named, in one line, not after the computing; so is a link to
    one."""
    said = (
        "is a mount point: the output replaces its folder whole, by a rename, which cannot "
        "move a mount point; give a folder inside it or elsewhere"
    )
    with pytest.raises(InvalidInputError, match=f"^--out /proc {said}$"):
        OutputFolder("/proc")
    (tmp_path / "link").symlink_to("/proc")
    run = run_cli("study", *NO_ROBOT, "--out", str(tmp_path / "link"))
    assert run.returncode == 2, run.stderr
    assert run.stderr == f"redundancy: error: --out {tmp_path / 'link'} {said}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link"]
