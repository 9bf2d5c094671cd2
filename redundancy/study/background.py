"""A computation run in a second process while this one goes on: the main job keeps both cores
of a machine busy.

`Background(function, *args)` forks a process that calls ``function(*args)`` and sends back its
result, or the exception it raised, through a pipe; `result()` waits for it and returns it, or
raises that exception here. Leaving the ``with`` block stops the process if its result was never
collected (an error or Ctrl-C in this process), so no computation outlives the command. The child
ignores Ctrl-C, which the terminal sends to both: this process decides; stopped, it ends at
once, whatever handlers it inherited. It dies with this process however that ends, SIGKILL
included (`die_with_parent`). What the child writes goes where its caller says: the
study's child writes only into the output's staging folder, which is kept only if the whole
command succeeds, so nothing a stopped child leaves can be seen half-written.

Where a fork would not be safe, the function runs in this process, at once: where the POSIX
``fork`` start method is missing, and where this process runs other threads (a notebook's
kernel, a Dask worker), since a forked child inherits the locks those threads hold but not the
threads that would release them. One lock is shared on purpose, and the child leaves it: the
progress bars' (tqdm guards its writes by a lock across processes, which a bar of this process
may hold at the fork, or take and never give back when Ctrl-C cuts its acquisition short); the
child takes a lock of its own, so that neither process waits for ever on the other's bars.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

STOPPING = {signal.SIGINT, signal.SIGTERM}
PR_SET_PDEATHSIG = 1  # prctl option, <linux/prctl.h>


def die_with_parent(parent: int) -> None:
    """Have the kernel send this process SIGKILL when its parent ``parent`` ends (Linux's
    parent-death signal); end now if it already has."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:
        os._exit(0)


def _run(sender: Connection, parent: int, function: Callable[..., Any], args: tuple) -> None:
    """In the child: call ``function(*args)``, send ("result", value) or ("error", e), and end
    at once (`os._exit`: no clean-up inherited from the parent runs, no buffered output of the
    parent's is written twice). It starts with `STOPPING` blocked (see `Background`)."""
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # `Background.stop`: end quietly, at once
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOPPING)
    if "tqdm" in sys.modules:  # a lock of the child's own for its progress bars (see above)
        sys.modules["tqdm"].tqdm.set_lock(threading.RLock())
    try:
        outcome: tuple[str, Any] = ("result", function(*args))
    except Exception as error:  # sent to the parent, which raises it there
        outcome = ("error", error)
    sender.send(outcome)
    sender.close()
    os._exit(0)


class Background:
    """``function(*args)`` computed in a forked process (see the module docstring)."""

    def __init__(self, function: Callable[..., Any], *args: Any) -> None:
        self._outcome: tuple[str, Any] | None = None
        self._process = None
        forkable = "fork" in multiprocessing.get_all_start_methods()
        if not forkable or threading.active_count() > 1:
            try:
                self._outcome = ("result", function(*args))
            except Exception as error:
                self._outcome = ("error", error)
            return
        context = multiprocessing.get_context("fork")
        self._receiver, sender = context.Pipe(duplex=False)
        self._process = context.Process(
            target=_run, args=(sender, os.getpid(), function, args), daemon=True
        )
        # a Ctrl-C at the fork would reach a child still running this process's handlers: it
        # waits, blocked, for the child's own, and is handled here once the child is started
        # (should it stop this constructor, the child is stopped; at the latest, as a daemon,
        # when this process exits)
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOPPING)
        try:
            self._process.start()
            sender.close()
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        except BaseException:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            self.stop()
            raise

    def result(self) -> Any:
        """The function's value, once it is computed; the exception it raised is raised here."""
        if self._outcome is None and self._process is not None:
            try:
                self._outcome = self._receiver.recv()
            except EOFError:  # the child died without answering (killed, out of memory)
                self._process.join()
                raise RuntimeError(
                    "the background computation ended without a result "
                    f"(exit code {self._process.exitcode})"
                ) from None
            self._process.join()
        assert self._outcome is not None
        kind, value = self._outcome
        if kind == "error":
            raise value
        return value

    def stop(self) -> None:
        """Stop the process if it is still computing."""
        if self._process is not None and self._process.is_alive():
            self._process.terminate()
            self._process.join()

    def __enter__(self) -> Background:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
