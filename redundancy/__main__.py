"""The ``redundancy`` command (and ``python -m redundancy``): Ctrl-C and SIGTERM end it with one
line from its first moment, while the libraries still load (`redundancy.study.signals`), and
`redundancy.cli.main` handles them from there on.

Its first statements hold the two signals back (blocked, not lost) until their handler is in
place: one that arrives while this module loads what the handler needs then ends the command
with that line, where Python's default would print a KeyboardInterrupt traceback. (The
interpreter's own start, before this module runs, is beyond its reach.) A signal after the
command's last exit function is ignored (`signals.ignored_at_exit`): it has finished."""

import signal

_before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})

import atexit  # noqa: E402  (after the signals are held back)
import gc  # noqa: E402
import sys  # noqa: E402

from redundancy.study import signals  # noqa: E402

signals.install()
atexit.register(signals.ignored_at_exit)  # the first exit function: it runs last
signal.pthread_sigmask(signal.SIG_SETMASK, _before)  # a signal held back is handled now


def main() -> int:
    """Run the command line (`redundancy.cli.main`) once it has loaded.

    Objects that live until the process ends are moved out of the garbage collector's sight
    (`gc.freeze`): the modules' once loaded, so that the collections of the command's run (and
    of the process the study forks) do not trace them again and again, and the command's own
    once it has returned, so that the interpreter's shutdown does not trace them all to free
    memory the process gives back as it exits (about a tenth of a study's wall time)."""
    from redundancy.cli import main as run

    gc.freeze()
    status = run()
    gc.freeze()
    return status


if __name__ == "__main__":
    sys.exit(main())
