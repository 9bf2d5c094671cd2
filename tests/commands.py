"""Running the command line as a user does: a separate process."""

import contextlib
import fcntl
import os
import pty
import signal
import struct
import subprocess
import sys
import termios


def run_cli(*args, cwd=None, timeout=None, terminal=False):
    """``redundancy ARGS`` (``python -m redundancy``) in a fresh interpreter; the completed
    process, text output. A run longer than ``timeout`` s is killed and raises
    `subprocess.TimeoutExpired`. With ``terminal``, its stderr is a terminal (where progress
    bars are drawn), whose text is returned as stderr."""
    command = [sys.executable, "-m", "redundancy", *args]
    if not terminal:
        return subprocess.run(command, capture_output=True, text=True, cwd=cwd, timeout=timeout)
    primary, secondary = pty.openpty()
    fcntl.ioctl(secondary, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # 80 columns
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=secondary, cwd=cwd) as run:
        os.close(secondary)
        shown = bytearray()
        with contextlib.suppress(OSError):  # EIO: the command has ended, the terminal closed
            while chunk := os.read(primary, 4096):
                shown += chunk
        os.close(primary)
        stdout = run.stdout.read()  # type: ignore[union-attr]
        run.wait(timeout)
    return subprocess.CompletedProcess(run.args, run.returncode, stdout.decode(), shown.decode())


def as_foreground() -> None:
    """A child's ``preexec_fn``: SIGINT as a foreground job has it. Where the suite itself runs
    as a background job of a shell without job control, its commands start with SIGINT
    ignored, and the command, as it should, keeps ignoring it: a Ctrl-C test would then test
    nothing."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
