"""A computation run in a second, forked process while this one goes on (the study command's
cycle section, and then its figures, on another core).

`Background(function, *args)` forks a process that calls ``function(*args)`` and sends back its
result, or the exception it raised, through a pipe; `result()` waits for it and returns it, or
raises that exception here. Leaving the ``with`` block stops the process if its result was never
collected (an error or Ctrl-C in this process), so no computation outlives the command. The child
ignores Ctrl-C, which the terminal sends to both (this process decides); stopped, it ends at once;
it dies with this process however that ends, SIGKILL included (`die_with_parent`).

Where a fork would not be safe, the function runs in this process, at once: where the POSIX
``fork`` start method is missing, and where this process runs other threads (a notebook's
kernel, a Dask worker), whose locks a forked child would inherit without the threads that
release them. The progress bars' lock, which tqdm shares across processes, is the child's own.
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


def _outcome(function: Callable[..., Any], args: tuple) -> tuple[str, Any]:
    try:
        return "result", function(*args)
    except Exception as error:  # raised where the result is collected
        return "error", error


def _run(sender: Connection, parent: int, function: Callable[..., Any], args: tuple) -> None:
    """In the child, started with `STOPPING` blocked: send ``function(*args)``'s `_outcome`,
    and end at once (`os._exit`: no clean-up or buffered output of the parent's runs twice)."""
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # `Background.stop`: end quietly, at once
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOPPING)
    if "tqdm" in sys.modules:
        sys.modules["tqdm"].tqdm.set_lock(threading.RLock())
    outcome = _outcome(function, args)
    try:
        sender.send(outcome)
    except Exception as error:  # a result that cannot be pickled: said there, in one line
        sender.send(("error", RuntimeError(f"its result cannot be sent back: {error}")))
    sender.close()
    os._exit(0)


class Background:
    """``function(*args)`` computed in a forked process (see the module docstring)."""

    def __init__(self, function: Callable[..., Any], *args: Any) -> None:
        self._outcome: tuple[str, Any] | None = None
        self._process = None
        if "fork" not in multiprocessing.get_all_start_methods() or threading.active_count() > 1:
            self._outcome = _outcome(function, args)
            return
        context = multiprocessing.get_context("fork")
        self._receiver, sender = context.Pipe(duplex=False)
        self._process = context.Process(
            target=_run, args=(sender, os.getpid(), function, args), daemon=True
        )
        # a signal at the fork would reach a child still running this process's handlers: it
        # waits, blocked, for the child's own, and is handled here once the child is started
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOPPING)
        try:
            self._process.start()
            sender.close()
        except BaseException:
            self.stop()
            raise
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

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
        kind, value = self._outcome  # type: ignore[misc]
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
