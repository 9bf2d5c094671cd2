"""All-or-nothing output: a run's files appear together, or not at all.

`OutputFolder` stages a run's whole output set (report, figures, pages, and files elsewhere
such as ``--json``, via `beside`) in fresh hidden places beside their targets, created before any
computing, so an unwritable target fails at once. `commit` swaps them in: under an exclusive
lock on the parent folder, with SIGINT and SIGTERM deferred (their handlers only note them until
the swap is done, whichever thread the kernel hands them to), the old folder is renamed aside,
the new one renamed into place, the other files renamed over theirs, and the old folder removed
(every staged file is flushed to the disk first, and the folders after, so a power cut never
leaves an empty file in place of a written one);
a rename that fails puts the old folder back. A run that fails or is interrupted before then
removes what it staged and the folders it made to stage it (those still empty), and leaves
every target as it was; two runs into one folder leave one complete output, the last to
commit. A target that holds files this toolkit did not write is
refused rather than replaced, when the run starts and again at the swap.

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
OWN_FILES = (
    "report.json",
    "map.parquet",
    "summary.json",
    "*.png",
    "*.html",
    MARKER,
)  # what an output folder may hold


def _unwritable(path: Path, error: OSError, option: str) -> InvalidInputError:
    reason = error.strerror or type(error).__name__
    return InvalidInputError(f"{option} {path}: cannot write there ({reason})")


class OutputFolder:
    """The output set of one run, staged beside ``target`` until `commit` (see the module
    docstring); ``option`` names where the target came from, for messages."""

    def __init__(self, target: Path | str, option: str = "--out"):
        self.target = Path(target)
        self.option = option
        if self.target.name in ("", ".", ".."):
            raise InvalidInputError(f"{option} {target}: give a folder by its own name")
        if self.target.exists() and not self.target.is_dir():
            raise InvalidInputError(f"{option} {self.target} is a file; give a folder")
        self._check_own()
        self.others: list[tuple[Path, Path]] = []  # (staged, final) files outside the folder
        parent = self.target.parent
        self.created = [f for f in (parent, *parent.parents) if not f.exists()]  # deepest first
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self.staging = Path(
                tempfile.mkdtemp(dir=self.target.parent, prefix=f".{self.target.name}.partial-")
            )
            (self.staging / MARKER).write_text("written by redundancy\n")
        except OSError as error:
            self.discard()
            raise _unwritable(self.target, error, option) from None

    def _check_own(self) -> None:
        """Refuse a target that holds files this toolkit did not write."""
        if not self.target.is_dir():
            return
        foreign = [
            entry.name
            for entry in self.target.iterdir()
            if not any(fnmatch.fnmatch(entry.name, own) for own in OWN_FILES)
        ]
        if foreign:
            raise InvalidInputError(
                f"{self.option} {self.target} holds files this toolkit did not write "
                f"({', '.join(sorted(foreign)[:3])}); give a new or empty folder, or an earlier "
                "output folder"
            )

    def __truediv__(self, name: str) -> Path:
        """Where the file ``name`` of the output set is written."""
        return self.staging / name

    def final(self, path: Path) -> Path:
        """Where a staged file will be once committed."""
        return self.target / path.relative_to(self.staging)

    def beside(self, path: Path, option: str) -> Path:
        """Where to write the output file ``path`` kept outside the folder (e.g. ``--json``): a
        temporary file beside it, renamed over it at `commit`."""
        staged = _temporary_beside(path, option)
        self.others.append((staged, path))
        return staged

    def commit(self) -> None:
        """Swap the staged set in for the targets, in one step for anyone who looks."""
        mode = 0o777 & ~_umask()
        self.staging.chmod(mode)  # mkdtemp makes it private; give a folder's mode
        for staged, _ in self.others:
            staged.chmod(mode & 0o666)
        for path in [*self.staging.rglob("*"), self.staging, *(s for s, _ in self.others)]:
            _sync(path)
        with _deferred_signals(), _locked(self.target.parent):
            self._check_own()  # a user may have saved files there while the run computed
            aside = Path(
                tempfile.mkdtemp(dir=self.target.parent, prefix=f".{self.target.name}.old-")
            )
            kept = aside / "output"
            try:
                if self.target.exists():
                    os.replace(self.target, kept)
                try:
                    os.replace(self.staging, self.target)
                except OSError:
                    if kept.exists():
                        os.replace(kept, self.target)
                    raise
                for staged, final in self.others:
                    os.replace(staged, final)
                for folder in {self.target.parent, *(final.parent for _, final in self.others)}:
                    _sync(folder)
            finally:
                shutil.rmtree(aside, ignore_errors=True)

    def discard(self) -> None:
        """Remove what was staged, and the folders made for it that are empty again; the
        targets are untouched."""
        if hasattr(self, "staging"):
            shutil.rmtree(self.staging, ignore_errors=True)
        for staged, _ in getattr(self, "others", []):
            staged.unlink(missing_ok=True)
        for folder in self.created:
            try:
                folder.rmdir()
            except OSError:  # it holds something (a map's chunks kept for a rerun)
                break

    def __enter__(self) -> OutputFolder:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is not None:
            self.discard()
            return
        try:
            self.commit()
        except BaseException:
            self.discard()
            raise


def _sync(path: Path) -> None:
    """Flush ``path`` (a file, or a folder's entries) to the disk, so that a rename made after
    it never exposes an empty or partial file after a power cut."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _umask() -> int:
    """The process's umask, read where the system shows it (setting it to read it would
    change it for an instant under every other thread)."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def _deferred_signals() -> Iterator[None]:
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


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive lock on ``folder`` (flock on its descriptor) for the block."""
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)


def _temporary_beside(path: Path, option: str) -> Path:
    """A new empty temporary file beside the file ``path`` (its folder is created); one line
    naming the option where ``path`` is a folder or cannot be written."""
    if path.is_dir() or path.name in ("", ".", ".."):
        raise InvalidInputError(f"{option} {path} is a folder; give a file path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        os.close(handle)
    except OSError as error:
        raise _unwritable(path, error, option) from None
    return Path(temporary)


def writable(path: Path | str, option: str) -> Path:
    """``path`` after checking that a file can be written beside it (its folder is created);
    one line naming the option otherwise."""
    path = Path(path)
    _temporary_beside(path, option).unlink()
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
        _sync(Path(temporary))
        os.replace(temporary, path)
        _sync(path.parent)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
