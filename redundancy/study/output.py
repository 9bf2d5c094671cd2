"""All-or-nothing output: a run's files appear together, or not at all.

`OutputFolder` stages a run's whole output set (report, figures, pages) in a fresh hidden
folder beside the target, created before any computing, so an unwritable target fails at once.
`commit` swaps it in: under an exclusive lock on the parent folder, with SIGINT and SIGTERM held
back, the old folder is renamed aside, the new one renamed into place and the old one removed. A
run that fails or is interrupted before then removes its staging folder and leaves the target as
it was; two runs into one folder leave one complete output, the last to commit. A target that
holds files this toolkit did not write is refused rather than replaced.

`write_atomically` writes one file the same way: to a temporary file beside it, then one rename.
"""

from __future__ import annotations

import contextlib
import fcntl
import fnmatch
import os
import shutil
import signal
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from redundancy.errors import InvalidInputError

MARKER = ".redundancy-output"  # names the folder as one this toolkit wrote
OWN_FILES = ("report.json", "*.png", "*.html", MARKER)  # what an output folder may hold


def _unwritable(path: Path, error: OSError, option: str) -> InvalidInputError:
    reason = error.strerror or type(error).__name__
    return InvalidInputError(f"{option} {path}: cannot write there ({reason})")


class OutputFolder:
    """The output set of one run, staged beside ``target`` until `commit` (see the module
    docstring); ``option`` names where the target came from, for messages."""

    def __init__(self, target: Path | str, option: str = "--out"):
        self.target = Path(target)
        self.option = option
        if self.target.exists() and not self.target.is_dir():
            raise InvalidInputError(f"{option} {self.target} is a file; give a folder")
        if self.target.is_dir():
            foreign = [
                entry.name
                for entry in self.target.iterdir()
                if not any(fnmatch.fnmatch(entry.name, own) for own in OWN_FILES)
            ]
            if foreign:
                raise InvalidInputError(
                    f"{option} {self.target} holds files this toolkit did not write "
                    f"({', '.join(sorted(foreign)[:3])}); give a new or empty folder, or an "
                    "earlier output folder"
                )
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            self.staging = Path(
                tempfile.mkdtemp(dir=self.target.parent, prefix=f".{self.target.name}.partial-")
            )
        except OSError as error:
            raise _unwritable(self.target, error, option) from None
        (self.staging / MARKER).write_text("written by redundancy\n")

    def __truediv__(self, name: str) -> Path:
        """Where the file ``name`` of the output set is written."""
        return self.staging / name

    def final(self, path: Path) -> Path:
        """Where a staged file will be once committed."""
        return self.target / path.relative_to(self.staging)

    def commit(self) -> None:
        """Swap the staged set in for the target, in one step for anyone who looks."""
        self.staging.chmod(0o777 & ~_umask())  # mkdtemp makes it private; give a folder's mode
        with _held_signals(), _locked(self.target.parent):
            aside = None
            if self.target.exists():
                aside = Path(
                    tempfile.mkdtemp(dir=self.target.parent, prefix=f".{self.target.name}.old-")
                )
                os.replace(self.target, aside / "output")
            os.replace(self.staging, self.target)
            if aside is not None:
                shutil.rmtree(aside)

    def discard(self) -> None:
        """Remove the staging folder; the target is untouched."""
        shutil.rmtree(self.staging, ignore_errors=True)

    def __enter__(self) -> OutputFolder:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.commit()
        else:
            self.discard()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def _held_signals() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block ends (then act as they would have)."""
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive lock on ``folder`` (flock on its descriptor) for the block."""
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)


def writable(path: Path | str, option: str) -> Path:
    """``path`` after checking that a file can be written beside it (its folder is created);
    one line naming the option otherwise."""
    path = Path(path)
    if path.is_dir():
        raise InvalidInputError(f"{option} {path} is a folder; give a file path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}."):
            pass
    except OSError as error:
        raise _unwritable(path, error, option) from None
    return path


def write_atomically(path: Path, write: Callable[[Path], object]) -> None:
    """Call ``write(temporary_path)``, then move the result over ``path`` in one step, so a
    failure never leaves ``path`` half-written or loses what it held."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix
    )
    os.close(handle)
    try:
        write(Path(temporary))
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes it private; give a file's mode
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
