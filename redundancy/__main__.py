"""The ``redundancy`` command (and ``python -m redundancy``): Ctrl-C and SIGTERM end it with one
line from its first moment, while the libraries still load (`redundancy.study.signals`), and
`redundancy.cli.main` handles them from there on."""

import sys

from redundancy.study import signals


def main() -> int:
    """Run the command line (`redundancy.cli.main`) once it has loaded."""
    signals.install()
    from redundancy.cli import main as run

    return run()


if __name__ == "__main__":
    sys.exit(main())
