"""A computation in a second process (`redundancy.study.background`): its value or its error
comes back, and no process outlives what started it, whether it is collected, abandoned,
killed, or the study that started it is interrupted."""

import ctypes
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest
from commands import as_foreground

from redundancy.errors import InvalidInputError
from redundancy.study.background import Background


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"  # ended, not yet reaped


def _refuse(value):
    raise InvalidInputError(f"value {value!r} is refused")


def _note_pid_then_sleep(path: Path) -> None:
    path.write_text(str(os.getpid()))
    time.sleep(60)


def _in_a_new_interpreter(case, *args) -> None:
    """``case(*args)`` run in a new interpreter, whose only thread is its main one. A test
    process may run threads that earlier tests left (a Dask client's), and beside them a
    `Background` computes in place: the fork these tests check would not happen, and a child's
    ``os._exit`` would end the test process itself."""
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=spawn) as interpreter:
        assert interpreter.submit(threading.active_count).result() == 1
        interpreter.submit(case, *args).result()


def _computed_in_another_process():
    with Background(os.getpid) as pending:
        assert pending.result() != os.getpid()
        assert pending.result() == pending.result()  # collected once, kept


def test_the_value_is_computed_in_another_process():
    _in_a_new_interpreter(_computed_in_another_process)


def test_beside_other_threads_the_value_is_computed_here():
    """A fork would copy locks held by threads it does not copy: with another thread running,
    the computation stays in this process, and answers the same way."""
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:
        with Background(os.getpid) as pending:
            assert pending.result() == os.getpid()
        with Background(_refuse, 1) as pending, pytest.raises(InvalidInputError):
            pending.result()
    finally:
        release.set()
        other.join()


def _error_raised_as_itself():
    with Background(_refuse, 3.5) as pending, pytest.raises(InvalidInputError) as raised:
        pending.result()
    assert str(raised.value) == "value 3.5 is refused"


PROGRESS_AT_THE_FORK = """
from tqdm import tqdm
from redundancy.study.background import Background

def counted():
    return sum(tqdm(range(3), disable=True))

with tqdm.get_lock():  # a bar of this process holds the bars' lock as the child starts
    print(Background(counted).result())
"""


def test_a_progress_bar_holding_its_lock_at_the_fork_stalls_neither_process():
    """tqdm's lock is shared across processes: a child that took the parent's would wait for
    ever on a lock the parent holds while it waits for the child."""
    done = subprocess.run(
        [sys.executable, "-c", PROGRESS_AT_THE_FORK],
        capture_output=True,
        text=True,
        timeout=600,  # guards a hang only
    )
    assert (done.returncode, done.stdout) == (0, "3\n"), done.stderr


def test_an_error_in_the_child_is_raised_here_as_itself():
    _in_a_new_interpreter(_error_raised_as_itself)


def _death_reported():
    with Background(os._exit, 3) as pending, pytest.raises(RuntimeError) as raised:
        pending.result()
    assert str(raised.value) == "the background computation ended without a result (exit code 3)"


def test_a_child_that_dies_without_an_answer_is_reported():
    _in_a_new_interpreter(_death_reported)


def _uncollected_child_stopped(note: Path):
    with Background(_note_pid_then_sleep, note) as pending:
        while not note.exists() or not note.read_text():
            time.sleep(0.01)
        pid = int(note.read_text())
        assert pid != os.getpid() and not _gone(pid)
    assert _gone(pid)
    assert pending._process.exitcode == -signal.SIGTERM  # stopped, not waited for


def test_leaving_the_block_uncollected_stops_the_child(tmp_path):
    _in_a_new_interpreter(_uncollected_child_stopped, tmp_path / "pid")


def _children(pid: int) -> list[int]:
    found = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True).stdout
    return [int(line) for line in found.split()]


def _foreground() -> None:
    """In the child: SIGINT as a foreground job has it (`as_foreground`), in a process group of
    its own."""
    as_foreground()
    os.setpgrp()


@pytest.mark.parametrize(
    ("stop", "status", "word"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
    ids=["ctrl-c", "terminate"],
)
def test_a_study_stopped_while_both_processes_compute_leaves_none(tmp_path, stop, status, word):
    """Stopped while the cycle section computes in its own process (Ctrl-C reaches the whole
    process group, as a terminal sends it; SIGTERM the command alone): one line, the exit
    status, no process left, nothing written."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "redundancy", "study", "--quiet", "--out", str(out)]
    run = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_foreground
    )
    deadline = time.monotonic() + 600
    while not (children := _children(run.pid)) and run.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert run.poll() is None, run.stderr.read()
    if stop == signal.SIGINT:
        os.killpg(run.pid, stop)
    else:
        run.send_signal(stop)
    _, errors = run.communicate(timeout=600)
    assert run.returncode == status and errors == f"redundancy: {word}\n"
    assert all(_gone(child) for child in children)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


PR_SET_CHILD_SUBREAPER = 36  # prctl option, <linux/prctl.h>


def _killed_study_leaves_no_child(out: str) -> None:
    """In a process that adopts its orphaned descendants: a study killed (SIGKILL) while its
    cycle section computes in the second process; that process, adopted, is found killed by
    the kernel (its parent-death signal), not computing on or ending by itself."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1)
    command = [sys.executable, "-m", "redundancy", "study", "--quiet", "--out", out]
    run = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 600
    while not (children := _children(run.pid)):
        assert time.monotonic() < deadline and run.poll() is None
        time.sleep(0.01)
    run.kill()
    run.wait()
    deadline = time.monotonic() + 600  # guards a hang only: a child computing on, or stuck
    while (ended := os.waitpid(children[0], os.WNOHANG)) == (0, 0):  # adopted: its parent died
        if time.monotonic() > deadline:
            os.kill(children[0], signal.SIGTERM)
            pytest.fail("the second process outlived the killed study")
        time.sleep(0.01)
    assert os.WIFSIGNALED(ended[1]) and os.WTERMSIG(ended[1]) == signal.SIGKILL, ended


def test_a_study_killed_leaves_no_process_computing(tmp_path):
    _in_a_new_interpreter(_killed_study_leaves_no_child, str(tmp_path / "out"))
