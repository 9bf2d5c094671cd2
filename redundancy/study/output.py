"""All-or-nothing output: a run's files appear together or not at all, and nothing else is lost.

`OutputFolder` stages a run's output in a hidden folder beside the target,
``.NAME.partial-PID-*``, made before any computing so that an unwritable target fails at once,
as does a mount point, which the commit's rename cannot move.
Its commit writes the manifest of the staged files into the folder's marker file (`MARKER`),
flushes them to the disk and exchanges the staged folder with the target in one rename (Linux's
``renameat2``): killed at any instant, the old or the new complete folder sits at the target.
SIGINT and SIGTERM wait for the end of the commit (`deferred`); a run that fails or is
interrupted before it removes what it staged, and the folders it made for it.

A folder is the toolkit's only if it carries the marker, and only the files its manifest names
are ever replaced or removed. A target without the marker that holds anything is refused; so is
one that holds, outside its manifest, a file of a name the new output writes. Anything else in an
earlier output (a user's notes, folders) is carried into the new one, with a note; a target that
appears while the run computes is left as it is. A new run removes the staging folders of runs
that died (by the pid in their name), with a note.

Files kept outside the folder (``--json``, `OutputFolder.beside`) are staged beside their
targets and renamed over them just after the exchange. The manifest names them, so that where a
run was killed in between, the next run into the same folder finishes those renames first, with
a note. A target that is a symbolic link stays one: what it names is written.
`write_atomically` writes one file the same way: a temporary file beside it, then `os.replace`.
"""

from __future__ import annotations

import array
import contextlib
import ctypes
import errno
import fcntl
import glob
import itertools
import json
import os
import re
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

from redundancy.errors import InvalidInputError
from redundancy.study.signals import check, deferred, written

MARKER = ".redundancy-output"  # names the folder as one this toolkit wrote; holds its manifest
RENAME_NOREPLACE, RENAME_EXCHANGE = 1, 2  # renameat2 flags, <linux/fs.h>
MOUNTS = Path("/proc/self/mountinfo")  # the kernel's mount table, where it has one
RENAMES = 100  # tries of the commit's rename while other runs change the target under it
FS_IOC_GETFLAGS = 0x80086601  # <linux/fs.h>: a file's flags, as lsattr reads them
UNCHANGEABLE = 0x10 | 0x20  # FS_IMMUTABLE_FL, FS_APPEND_FL


def _unwritable(path: Path, error: OSError, option: str) -> InvalidInputError:
    reason = error.strerror or type(error).__name__
    return InvalidInputError(f"{option} {path}: cannot write there ({reason})")


def _note(message: str) -> None:
    """One line for the user (the command line prints warnings as notes)."""
    warnings.warn(message, stacklevel=3)


def _followed(path: Path, option: str) -> Path:
    """What the symbolic link ``path`` names (dangling or not), or ``path``; one line naming
    the ``option`` where the links lead round in a loop."""
    if not path.is_symlink():
        return path
    try:
        return Path(os.path.realpath(path, strict=True))
    except FileNotFoundError:  # dangling: its target is made
        return Path(os.path.realpath(path))
    except OSError as error:
        raise _unwritable(path, error, option) from None


def inside_output(path: Path, option: str) -> None:
    """Refuse, in one line naming the ``option``, a file ``path`` inside an output folder of
    the toolkit's, whose files its manifest keeps together."""
    for folder in Path(os.path.abspath(path)).parents:
        if _manifest(folder) is not None:
            raise InvalidInputError(
                f"{option} {path} lies in {folder}, an output folder this toolkit wrote, "
                "whose files belong together; give a path outside it"
            )


def _hidden(path: Path, kind: str) -> Path:
    """A new hidden name beside ``path``: ``.NAME.KIND-PID-RANDOM``, its owner's pid in it."""
    return path.parent / f".{path.name}.{kind}-{os.getpid()}-{os.urandom(4).hex()}"


def _make_parent(path: Path, option: str) -> list[Path]:
    """Create ``path``'s folder; the folders that made, outermost first. One line naming the
    option where a file stands in its way."""
    missing = list(itertools.takewhile(lambda p: not p.exists(), path.parents))
    if len(missing) < len(path.parents) and not (blocking := path.parents[len(missing)]).is_dir():
        raise InvalidInputError(f"{option} {path}: {blocking} is a file, not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    return missing[::-1]


def _rename(source: Path, target: Path, flags: int) -> None:
    """``renameat2(source, target, flags)``: RENAME_EXCHANGE swaps the two paths in one step,
    RENAME_NOREPLACE fails (FileExistsError) where ``target`` exists. Where the C library or the
    file system lacks it, the same by plain renames, with an instant between them."""
    function = getattr(ctypes.CDLL(None, use_errno=True), "renameat2", None)
    if function is not None:
        at_cwd = -100  # AT_FDCWD: paths relative to the current folder
        if function(at_cwd, os.fsencode(source), at_cwd, os.fsencode(target), flags) == 0:
            return
        number = ctypes.get_errno()
        if number not in (errno.EINVAL, errno.ENOSYS):
            raise OSError(number, os.strerror(number), str(source), None, str(target))
    if flags == RENAME_EXCHANGE:
        aside = _hidden(target, "old")
        os.replace(target, aside)
        os.replace(source, target)
        os.replace(aside, source)
    elif os.path.lexists(target):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(target))
    else:
        os.rename(source, target)


def _manifest(folder: Path) -> dict | None:
    """The marker of ``folder``, read: ``{"files": [...], "beside": [[staged, final], ...]}``,
    files None for a folder still staging (everything in it is the run's); None for a folder
    without the marker, which is not the toolkit's."""
    try:
        found = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError):
        return None
    return found if isinstance(found, dict) and "files" in found else None


def _retire(folder: Path, into: Path, manifest: dict) -> None:
    """Remove an earlier output (or a dead run's staging folder) ``folder`` of ``manifest``:
    anything the manifest does not name is first carried into ``into``, with a note; then the
    files it names and stages beside go, the marker last, and the folder. A staging folder not
    yet committed (files None) goes whole. What cannot be carried (its name taken in ``into``)
    stays, with the marker, so that it is never taken for the run's."""
    for staged, _ in manifest.get("beside", []):
        with contextlib.suppress(OSError):
            Path(staged).unlink()
    if manifest["files"] is None:
        shutil.rmtree(folder, ignore_errors=True)
        return
    own = {Path(name).parts[0] for name in manifest["files"]} | {MARKER}
    carried, left = [], []
    for entry in sorted(folder.iterdir()):
        if entry.name not in own:
            try:
                _rename(entry, into / entry.name, RENAME_NOREPLACE)
                carried.append(entry.name)
            except OSError:
                left.append(entry.name)
    if carried:
        _note(f"{into}: kept {', '.join(carried)}, which redundancy did not write")
    for name in manifest["files"]:
        (folder / name).unlink(missing_ok=True)
        for parent in Path(name).parents[:-1]:
            with contextlib.suppress(OSError):
                (folder / parent).rmdir()
    if left:
        _note(f"{folder}: kept, as it holds {', '.join(left)}, names {into} holds too")
        return
    (folder / MARKER).unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        folder.rmdir()


def _retired(folder: Path, into: Path, manifest: dict) -> bool:
    """`_retire`, and where the file system refuses (a file of the earlier output made
    immutable, say), a note that names the folder left: the run's own output is whole, and the
    next run into the same folder tries again. Whether the folder is gone."""
    try:
        _retire(folder, into, manifest)
    except OSError as error:
        reason = error.strerror or type(error).__name__
        _note(f"{folder}: could not remove this earlier output ({reason}); remove it by hand")
    return not folder.exists()


def _alive(pid: str) -> bool:
    """Whether the process ``pid`` runs (a name that is no pid, or another user's process,
    counts as running)."""
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (ValueError, PermissionError):
        pass
    return True


def _clean_up_after_killed_runs(target: Path) -> None:
    """Finish the renames beside ``target`` that a killed run's commit left, and remove
    (`_retire`) the staging folders of runs that died; a note for each."""
    for staged, final in (_manifest(target) or {}).get("beside", []):
        if os.path.exists(staged):
            os.replace(staged, final)
            _note(f"{final}: finished writing it, as the run that wrote {target} was stopped first")
    prefix = f".{target.name}.partial-"
    found = sorted(target.parent.glob(f"{glob.escape(prefix)}*"))
    dead = [f for f in found if not _alive(f.name.removeprefix(prefix).partition("-")[0])]
    removed = [f for f in dead if _retired(f, target, _manifest(f) or {"files": None})]
    if removed:
        _note(f"removed {', '.join(f.name for f in removed)}: staged by runs that were stopped")


class OutputFolder:
    """The output set of one run, staged beside ``target`` until `commit` (see the module
    docstring); ``option`` names where the target came from, for messages."""

    def __init__(self, target: Path | str, option: str = "--out"):
        self.option = option
        self.others: list[tuple[Path, Path]] = []  # (staged, final) files outside the folder
        self.created: list[Path] = []  # the folders made to hold the target, outermost first
        self._committed = False
        try:
            self.target = _followed(Path(target), option)
            if self.target.name in ("", ".", ".."):
                raise InvalidInputError(f"{option} {target}: give a folder by its own name")
            if _mount_point(self.target):  # refused now, not after the computing
                raise InvalidInputError(
                    f"{option} {target} is a mount point: the output replaces its folder whole, "
                    "by a rename, which cannot move a mount point; give a folder inside it or "
                    "elsewhere"
                )
            inside_output(self.target, option)
            self._check_target()
            self.created = _make_parent(self.target, option)
            _clean_up_after_killed_runs(self.target)
            self.staging = _hidden(self.target, "partial")
            self.staging.mkdir()
            self._mark(None)
        except OSError as error:
            self.discard()
            raise _unwritable(Path(target), error, option) from None
        except BaseException:  # a signal while staging: no `with` block will discard it
            self.discard()
            raise

    def _check_target(self, writing: tuple[str, ...] = ()) -> bool:
        """Whether the target exists; one line where it is not an output folder of the
        toolkit's (or an empty folder), or holds, outside its manifest, one of ``writing``."""
        if not self.target.exists():
            return False
        if not self.target.is_dir():
            what = "a file" if self.target.is_file() else "a device, a pipe or a socket"
            raise InvalidInputError(f"{self.option} {self.target} is {what}; give a folder")
        manifest = _manifest(self.target)
        names = sorted(e.name for e in self.target.iterdir())
        if names and not os.access(self.target, os.W_OK | os.X_OK):  # read-only, immutable
            raise InvalidInputError(
                f"{self.option} {self.target}: cannot write there (the folder is not "
                "writable: the output replaces it whole, and removes what it replaces)"
            )
        if manifest is None and names:
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
            raise InvalidInputError(
                f"{self.option} {self.target} holds files this toolkit did not write ({shown}); "
                "give a new or empty folder, or an earlier output folder"
            )
        own = {Path(f).parts[0] for f in (manifest or {}).get("files", [])}
        if clashing := sorted(set(names) & set(writing) - own):
            raise InvalidInputError(
                f"{self.option} {self.target} holds {', '.join(clashing)}, which this toolkit "
                "did not write; move it, or give another folder"
            )
        return True

    def __truediv__(self, name: str) -> Path:
        """Where the file ``name`` of the output set is written."""
        return self.staging / name

    def final(self, path: Path) -> Path:
        """Where a staged file will be once committed."""
        return self.target / path.relative_to(self.staging)

    def beside(self, path: Path, option: str) -> Path:
        """Where to write the output file ``path`` kept outside the folder (e.g. ``--json``): a
        hidden file beside it, named in the staging folder's marker before it is made, renamed
        over it at `commit`. ``path`` may not be the folder, lie inside it or hold it."""
        path = _followed(path, option)
        a, b = Path(os.path.abspath(path)), Path(os.path.abspath(self.target))
        if a == b or a in b.parents or b in a.parents:
            raise InvalidInputError(
                f"{option} {path} overlaps {self.option} {self.target}; give a file outside "
                f"that folder (it holds its own report.json)"
            )
        inside_output(path, option)
        suffix = self.staging.name.removeprefix(f".{self.target.name}")
        staged = path.parent / f".{path.name}{suffix}"
        self.others.append((staged, path))
        self._mark(None)
        self.created += _create_beside(path, staged, option)
        return staged

    def _mark(self, files: list[str] | None) -> None:
        """Write the marker, atomically: the manifest of ``files`` (None: still staging) and of
        the files staged beside."""
        beside = [[str(staged), str(final)] for staged, final in self.others]
        text = json.dumps({"files": files, "beside": beside}, indent=1) + "\n"
        write_atomically(self.staging / MARKER, lambda path: path.write_text(text))

    def commit(self) -> None:
        """Exchange the staged folder with the target, then rename the files beside it; the
        earlier output is retired (`_retire`). A signal a library swallowed on the way
        (`signals.check`) is raised first: nothing is committed."""
        check()
        files = [p for p in self.staging.rglob("*") if p.is_file() and p.name != MARKER]
        self._mark(sorted(str(p.relative_to(self.staging)) for p in files))
        for path in [*self.staging.rglob("*"), self.staging, *(s for s, _ in self.others)]:
            _sync(path)
        writing = tuple({p.relative_to(self.staging).parts[0] for p in files})
        with deferred():
            for attempt in itertools.count():  # until the rename finds the target as checked
                exists = self._check_target(writing)
                try:
                    flags = RENAME_EXCHANGE if exists else RENAME_NOREPLACE
                    _rename(self.staging, self.target, flags)
                    break
                except (FileExistsError, FileNotFoundError):
                    if not self.staging.is_dir() or attempt == RENAMES:
                        raise
            self._committed = True
            refused = []  # where the check before any computing could not tell
            written.append(str(self.target))
            for staged, final in self.others:
                try:
                    os.replace(staged, final)
                    written.append(str(final))
                except OSError as error:
                    with contextlib.suppress(OSError):
                        staged.unlink()
                    refused.append(f"{final}: cannot write there ({error.strerror})")
            for folder in {self.target.parent, *(final.parent for _, final in self.others)}:
                _sync(folder)
            if exists:  # the earlier output, now where the staged one was
                _retired(self.staging, self.target, _manifest(self.staging) or {"files": []})
            if refused:
                raise InvalidInputError(f"{'; '.join(refused)}; {self.target} was written whole")

    def discard(self) -> None:
        """Before the commit, remove what was staged, and the folders made for it where they
        are empty again; the targets are untouched."""
        if self._committed:
            return
        if hasattr(self, "staging"):
            shutil.rmtree(self.staging, ignore_errors=True)
        for staged, _ in self.others:
            with contextlib.suppress(OSError):  # never made, or its folder not either
                staged.unlink()
        for folder in reversed(self.created):
            with contextlib.suppress(OSError):
                folder.rmdir()

    def __enter__(self) -> OutputFolder:
        return self

    def shown(self, path: Path | str) -> Path:
        """The path the user gave for ``path``: the target for anything in the staging folder,
        the final file for one staged beside it; ``path`` itself otherwise."""
        path = Path(path)
        if path == self.staging or self.staging in path.parents:
            return self.target
        return next((final for staged, final in self.others if staged == path), path)

    def __exit__(self, kind, value, traceback) -> None:
        try:
            if kind is None:
                self.commit()
            elif isinstance(value, OSError) and value.filename is not None:
                value.filename = str(self.shown(value.filename))  # for its message
        except OSError as error:
            raise _unwritable(self.target, error, self.option) from None
        finally:
            self.discard()  # nothing once committed


def _sync(path: Path) -> None:
    """Flush ``path`` (a file, or a folder's entries) to the disk, so that a rename made after
    it never exposes an empty or partial file after a power cut."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _create_beside(path: Path, staged: Path, option: str) -> list[Path]:
    """Create the empty file ``staged`` beside the file ``path``; the folders made to hold it.
    One line naming the option where ``path`` cannot be written, or is a folder or anything
    else but a regular file (a device or a pipe, which the rename would replace)."""
    try:
        if path.is_dir() or path.name in ("", ".", ".."):
            raise InvalidInputError(f"{option} {path} is a folder; give a file path")
        if path.exists() and not path.is_file():
            raise InvalidInputError(
                f"{option} {path} is not a regular file (a device, pipe or socket); give a "
                "file path"
            )
        if path.is_file() and _unchangeable(path):
            raise InvalidInputError(
                f"{option} {path}: cannot write there (the file is marked immutable or "
                "append-only, and the output replaces it whole)"
            )
        created = _make_parent(path, option)
        staged.open("x").close()
    except OSError as error:
        raise _unwritable(path, error, option) from None
    return created


def _unchangeable(path: Path) -> bool:
    """Whether the file ``path`` is marked immutable or append-only (``chattr +i``, ``+a``),
    which no rename may replace (Linux's file flags); False where they cannot be read."""
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        flags = array.array("i", [0])  # the kernel writes an int
        fcntl.ioctl(descriptor, FS_IOC_GETFLAGS, flags)
        return bool(flags[0] & UNCHANGEABLE)
    except OSError:  # a file system without the flags
        return False
    finally:
        os.close(descriptor)


def writable(path: Path | str, option: str) -> Path:
    """``path`` (where it links to, for a link) after checking that a file can be written
    beside it (its folder is created) and that it lies in no output folder of the toolkit's
    (`inside_output`); one line naming the option otherwise."""
    path = _followed(Path(path), option)
    inside_output(path, option)
    staged = _hidden(path, "check")
    _create_beside(path, staged, option)
    staged.unlink()
    return path


def write_atomically(path: Path, write: Callable[[Path], object]) -> None:
    """Call ``write(temporary_path)``, then move the result over ``path`` in one step, so a
    failure never leaves ``path`` half-written or loses what it held. A ``path`` that is a
    folder, anything but a regular file (a device or a pipe, which the move would replace) or
    cannot be written is refused in one line (`_create_beside`); a write that fails (a full
    disk) raises its error naming ``path``."""
    temporary = Path(f"{_hidden(path, 'new')}{path.suffix}")  # a writer may read the suffix
    try:
        _create_beside(path, temporary, "output")
        write(temporary)
        _sync(temporary)
        try:
            os.replace(temporary, path)
        except OSError as error:  # the file system refused (an immutable file there)
            if error.errno not in (errno.EPERM, errno.EACCES, errno.EROFS):
                raise
            raise InvalidInputError(f"{path}: cannot write there ({error.strerror})") from None
        _sync(path.parent)
    except BaseException as error:
        with contextlib.suppress(OSError):  # where it could not be made, the first error says why
            temporary.unlink(missing_ok=True)
        if isinstance(error, OSError) and error.filename is None:  # a write (a full disk)
            error.filename = str(path)
        raise


def _mount_point(path: Path) -> bool:
    """Whether ``path`` is a mount point: one `os.path.ismount` sees (another device, or the
    root), or a bind mount on the same device (a container's volume), which only the kernel's
    mount table lists (its fifth field, with space, tab, newline and backslash as octal)."""
    if os.path.ismount(path):
        return True
    try:
        table = MOUNTS.read_text(errors="surrogateescape")
    except OSError:
        return False
    resolved = os.path.realpath(path)
    points = (line.split()[4] for line in table.splitlines() if len(line.split()) > 4)
    return any(re.sub(r"\\([0-7]{3})", _octal, point) == resolved for point in points)


def _octal(match: re.Match) -> str:
    """The character an octal escape of the mount table stands for."""
    return chr(int(match.group(1), 8))
