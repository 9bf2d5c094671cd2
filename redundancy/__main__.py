"""The ``redundancy`` command (and ``python -m redundancy``): Ctrl-C and SIGTERM end it with one
line from its first moment, while the libraries still load (`redundancy.study.signals`), and
`redundancy.cli.main` handles them from there on."""

import gc
import sys

from redundancy.study import signals


def main() -> int:
    """Run the command line (`redundancy.cli.main`) once it has loaded. Its objects are then
    left to the process's end (`gc.freeze`): the interpreter's shutdown would otherwise trace
    them all in its garbage collections, about a tenth of a study's wall time, to free memory
    the process gives back as it exits."""
    signals.install()
    from redundancy.cli import main as run

    status = run()
    gc.freeze()
    return status


if __name__ == "__main__":
    sys.exit(main())
