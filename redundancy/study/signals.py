"""Ctrl-C and SIGTERM: one handler, `stop`, from the command's first moment to its end.

Until the command runs (`caught`), while the libraries load and nothing needs cleaning up, a
signal ends the process at once: one line, exit status 130 (interrupted) or 143 (terminated),
and no exception that an import could turn into another or print half-way. Within `caught` it
raises KeyboardInterrupt, or `Terminated` for SIGTERM, where the program is, so that clean-ups
run (a staging folder removed, a background process stopped, a server taken down) and the
command ends with that line and status. `received` keeps the signals for where a library turned
the exception into another, or Python could only ignore it (raised in a weakref callback; that
report is silenced). `deferred` holds them back through a block that must not be cut short.

A command started with SIGINT ignored (a shell's background job: a Ctrl-C meant for the
foreground leaves it running) keeps ignoring it, unless ``interrupt=True`` (play's loop).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Iterator

received: list[int] = []  # the signals received, whatever a library made of their exceptions
_raising = False  # within `caught`: raise where the program is; before it, end at once


class Terminated(BaseException):
    """SIGTERM, raised where the program is so that clean-ups run as for Ctrl-C."""


def ending(number: int) -> tuple[str, int]:
    """The word and the exit status for the signal ``number``."""
    return ("terminated", 143) if number == signal.SIGTERM else ("interrupted", 130)


def stop(number: int, frame) -> None:
    """The handler of SIGINT and SIGTERM (see the module docstring)."""
    received.append(number)
    if not _raising:
        word, status = ending(number)
        os.write(2, f"redundancy: {word}\n".encode())
        os._exit(status)
    raise Terminated if number == signal.SIGTERM else KeyboardInterrupt


def install(interrupt: bool = False) -> dict:
    """`stop` for SIGTERM, and for SIGINT unless it is ignored (and not ``interrupt``); the
    handlers it replaced."""
    numbers = [signal.SIGTERM]
    if interrupt or signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        numbers.append(signal.SIGINT)
    return {number: signal.signal(number, stop) for number in numbers}


@contextlib.contextmanager
def caught(interrupt: bool = False) -> Iterator[None]:
    """`stop` raising where the program is, for the block (`install`); then as before."""
    global _raising
    received.clear()
    previous, was_raising, _raising = install(interrupt), _raising, True
    unraisable, sys.unraisablehook = sys.unraisablehook, _unraisable
    try:
        yield
    finally:
        _raising, sys.unraisablehook = was_raising, unraisable
        for number, handler in previous.items():
            signal.signal(number, handler)


def _unraisable(report) -> None:
    """Python's report of an exception it had to ignore, silenced for the signals' own (the
    signal stays in `received`)."""
    if not isinstance(report.exc_value, KeyboardInterrupt | Terminated):
        sys.__unraisablehook__(report)


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """SIGINT and SIGTERM only noted during the block, then handled as they would have been.

    Python runs signal handlers in the main thread, whichever thread the kernel delivered the
    signal to, so swapping the handlers (rather than masking one thread) covers them all."""
    noted: list[int] = []
    numbers = (signal.SIGINT, signal.SIGTERM)
    previous = {n: signal.signal(n, lambda number, frame: noted.append(number)) for n in numbers}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        for noted_number in noted:
            handler = previous[signal.Signals(noted_number)]
            if callable(handler):
                handler(noted_number, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(noted_number)
