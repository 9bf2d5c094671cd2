"""The ``redundancy`` command (and ``python -m redundancy``): Ctrl-C and SIGTERM end it with one
line from its first moment, while the libraries still load, and `redundancy.cli.main` handles
them from there on."""

import signal
import sys


def _during_start_up(number: int, frame) -> None:
    terminated = number == signal.SIGTERM
    print(f"redundancy: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
    raise SystemExit(143 if terminated else 130)


def main() -> int:
    """Run the command line (`redundancy.cli.main`) once it has loaded."""
    signal.signal(signal.SIGTERM, _during_start_up)
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:  # a background job keeps it off
        signal.signal(signal.SIGINT, _during_start_up)
    from redundancy.cli import main as run

    return run()


if __name__ == "__main__":
    sys.exit(main())
