"""Running the command line as a user does: a separate process."""

import subprocess
import sys


def run_cli(*args, cwd=None, timeout=None):
    """``redundancy ARGS`` in a fresh interpreter; the completed process, text output. A run
    longer than ``timeout`` s is killed and raises `subprocess.TimeoutExpired`."""
    return subprocess.run(
        [sys.executable, "-m", "redundancy.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
    )
