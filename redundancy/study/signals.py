"""Ctrl-C and SIGTERM: one handler, `stop`, from the command's first moment to its end.

Until the command runs (`caught`), while the libraries load and nothing needs cleaning up, a
signal ends the process at once: one line, exit status 130 (interrupted) or 143 (terminated),
and no exception that an import could turn into another or print half-way. Within `caught` it
raises KeyboardInterrupt, or `Terminated` for SIGTERM, where the program is, so that clean-ups
run (a staging folder removed, a server taken down) and the command ends with that line and
status. `received` keeps the signals for where a library turned the exception into another, or
Python could only ignore it (raised in a weakref callback; that report is silenced). Within
`deferred` it only notes them, for the end of a block that must not be cut short.

Threads started within `unheard` (and every process they start) never receive SIGINT: a
terminal's Ctrl-C reaches the whole process group, and the command alone answers it.

A command started with SIGINT ignored (a shell's background job: a Ctrl-C meant for the
foreground leaves it running) keeps ignoring it, unless ``interrupt=True`` (play's loop).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable, Iterator

STOPPING = (signal.SIGINT, signal.SIGTERM)
received: list[int] = []  # the signals received, whatever a library made of their exceptions
_raising = False  # within `caught`: raise where the program is; before it, end at once
_held: list[int] | None = None  # within `deferred`: the signals noted, handled at its end
_announced = False  # the line that the command ends by a signal is written
written: list[str] = []  # the outputs the command has committed whole, for that line


class Terminated(BaseException):
    """SIGTERM, raised where the program is so that clean-ups run as for Ctrl-C."""


def announce(number: int, write: Callable[[str], object] | None = None) -> int:
    """Write the line that says the command ends by the signal ``number``, by ``write`` (by
    default straight to the standard error's descriptor, as a handler may); once in a command's
    run, so that a second Ctrl-C while it ends adds no second line. Its exit status: 130
    interrupted, 143 terminated."""
    global _announced
    word, status = ("terminated", 143) if number == signal.SIGTERM else ("interrupted", 130)
    if not _announced:
        _announced = True
        done = f" after writing {', '.join(written)} whole" if written else ""
        line = f"redundancy: {word}{done}\n"
        write(line) if write else os.write(2, line.encode())
    return status


def stop(number: int, frame) -> None:
    """The handler of SIGINT and SIGTERM (see the module docstring)."""
    if _held is not None:
        _held.append(number)
        return
    received.append(number)
    if not _raising:
        os._exit(announce(number))
    raise Terminated if number == signal.SIGTERM else KeyboardInterrupt


def install(interrupt: bool = False) -> dict:
    """`stop` for SIGTERM, and for SIGINT unless it is ignored (and not ``interrupt``); the
    handlers it replaced."""
    numbers = [signal.SIGTERM]
    if interrupt or signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        numbers.append(signal.SIGINT)
    return {number: signal.signal(number, stop) for number in numbers}


def ignored_at_exit() -> None:
    """SIGINT and SIGTERM ignored from here to the process's end. The command registers it as
    its first exit function, so that it runs last, once its own (a child joined, a server taken
    down) are done and the command has finished: the interpreter's end then puts the default
    actions back, which would end the finished command by the signal, without its line."""
    for number in STOPPING:
        signal.signal(number, signal.SIG_IGN)


def check() -> None:
    """Within `caught`, raise a signal received that a library swallowed (`received`) where
    the program is now: a long loop stops at its next turn, and a block that must not outlast
    the signal (an output's commit) does not begin."""
    if _raising and received:
        raise Terminated if received[-1] == signal.SIGTERM else KeyboardInterrupt


@contextlib.contextmanager
def caught(interrupt: bool = False) -> Iterator[None]:
    """`stop` raising where the program is, for the block (`install`); then as before."""
    global _raising, _announced
    received.clear()
    written.clear()
    _announced = False
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
    """SIGINT and SIGTERM only noted (by `stop`) during the block, then handled as the handlers
    in place before it would have: Python runs handlers in the main thread, whichever thread
    the kernel delivered the signal to, so a handler (not a thread's mask) covers them all."""
    global _held
    outer, _held = _held, []
    previous = {number: signal.signal(number, stop) for number in STOPPING}
    try:
        yield
    finally:
        noted, _held = _held, outer
        for number, handler in previous.items():
            signal.signal(number, handler)
        for late in noted:
            if callable(handler := previous[signal.Signals(late)]):
                handler(late, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(late)


@contextlib.contextmanager
def unheard() -> Iterator[None]:
    """SIGINT blocked in the threads started during the block, for good, and so in every
    process they start (a child inherits its thread's mask, across exec): a Ctrl-C at a
    terminal, which reaches the whole process group, leaves such a child alone from its first
    instruction, where a handler of its own could only be installed once its imports are done.
    The calling thread's mask is restored at the end: a Ctrl-C during the block reaches the
    command then, or at once through another of its threads."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
