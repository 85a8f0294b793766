"""Output folders and files: nothing of the user's is ever deleted, moved or replaced.

The rules, one mechanism for every command that writes (solve, figures, study, extremes into a
folder; check --json and bench --out into one file):

- Before any work the target is claimed (`output_folder` / `output_file`): its parents must be
  folders, it must be creatable and writable (not under a regular file, not read-only, not a
  virtual file system); otherwise SceneError naming the option and path (exit 2, nothing run).
- A folder that exists and holds files which no run marker lists is refused (SceneError naming
  the folder and one such file) unless `overwrite`: then mixvi writes its files beside the
  others (replacing only files of the same names) and still deletes nothing it did not write.
  A folder without a marker whose files all carry names mixvi writes (an earlier mixvi version's
  output) counts as mixvi's.
- A claimed folder is locked (`.mixvi-lock`, an flock): a second run into it is refused.
- Files are written into a staging folder inside the target and committed at the end: each
  file renamed into place, the files the previous run listed and this one does not write again
  removed (nothing else), and the marker `.mixvi-run.json` (command, version, time, files)
  written last. The commit runs with signals deferred; on an error or a signal before it, the
  staging folder is removed and the target is as it was.
- A single file the user names is written beside it and renamed over it (atomic replace).
- Folders and files get the user's umask.
"""

from __future__ import annotations

import datetime
import errno
import fcntl
import json
import os
import shutil
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np

from problems.errors import SceneError

from .signals import deferred

MARKER = ".mixvi-run.json"
LOCK = ".mixvi-lock"
STAGING = ".mixvi-tmp-"  # prefix of staging folders and temporary files
# an unmarked folder whose files all end like this, with one of LEGACY_NAMES among them, was
# written by an earlier mixvi version (before the marker existed)
LEGACY_SUFFIXES = (".json", ".vtu", ".png")
LEGACY_NAMES = ("summary.json", "study.json", "extremes.json", "fig_5_4.png")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mixvi")
    except PackageNotFoundError:
        return "unknown"


def _refuse(option: str, path: Path, allowed: str) -> SceneError:
    return SceneError(option, str(path), allowed)


def _create_dirs(path: Path, option: str) -> list[Path]:
    """mkdir -p `path` (user's umask); the folders created, outermost first. SceneError if a
    parent is a file or a folder cannot be created."""
    missing = []
    p = path
    while not p.exists():
        if p.is_symlink():  # a dangling link: do not write through it
            raise _refuse(option, path, f"a folder path; {p} is a broken symbolic link")
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise _refuse(option, path, f"a folder path whose parents are folders; {p} is a file")
    created = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            if not d.is_dir():
                raise _refuse(option, path, f"a folder path; {d} is a file") from None
            continue
        except OSError as err:
            _remove_empty(created)
            raise _refuse(
                option, path, f"a folder mixvi can create ({_reason(err)} at {d})"
            ) from None
        created.append(d)
    return created


def _reason(err: OSError) -> str:
    return {
        errno.EROFS: "read-only file system",
        errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted",
        errno.ENOSPC: "no space left on device: free space, or choose another file system",
        errno.EDQUOT: "disk quota exceeded: free space, or choose another file system",
        errno.EFBIG: "the file-size limit (ulimit -f) was reached: raise it",
        errno.ENOTDIR: "a parent is not a folder",
        errno.ENAMETOOLONG: "a name too long for the file system",
        errno.ELOOP: "too many symbolic links",
    }.get(err.errno, err.strerror or type(err).__name__)


def _why(err: Exception) -> str:
    return _reason(err) if isinstance(err, OSError) else str(err)


def _remove_empty(created: list[Path]) -> None:
    """Remove the folders this run created (innermost first) if they are still empty."""
    for d in reversed(created):
        with suppress(OSError):
            d.rmdir()


def _prune(root: Path, rel: Path) -> None:
    """Remove the folder `root/rel` and its parents below `root` while they are empty (the
    subfolders of a run's files, e.g. levels/1/, once those files are gone); a folder that
    holds anything stays."""
    while rel.parts:
        try:
            (root / rel).rmdir()
        except OSError:  # not empty (or already gone): stop
            return
        rel = rel.parent


def _iter_files(root: Path) -> Iterator[str]:
    """Relative paths of the non-folder entries under `root`, top level first (mixvi's own
    bookkeeping and staging entries left out)."""
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(STAGING))
        rel = Path(dirpath).relative_to(root)
        for f in sorted(filenames):
            if f in (MARKER, LOCK) or f.startswith(STAGING):
                continue
            yield str(rel / f) if str(rel) != "." else f


def _files(root: Path) -> list[str]:
    return list(_iter_files(root))


def first_foreign(folder: Path) -> str | None:
    """A file in `folder` that no mixvi run wrote (None: every file is mixvi's).

    With a marker, the files it lists are mixvi's; without one, the folder is an earlier
    mixvi version's output if every file ends in LEGACY_SUFFIXES and one is in LEGACY_NAMES.
    Stops at the first foreign file (a hostile target such as / is not walked through).
    """
    marker = read_marker(folder)
    listed = {str(f) for f in [*marker["files"], *marker.get("earlier", [])]} if marker else None
    first, legacy_name = None, False
    for f in _iter_files(folder):
        if listed is not None:
            if f not in listed:
                return f
            continue
        if not f.endswith(LEGACY_SUFFIXES):
            return f
        first = first or f
        legacy_name = legacy_name or Path(f).name in LEGACY_NAMES
    return first if listed is None and not legacy_name else None


def read_marker(folder: Path) -> dict | None:
    """The run marker of `folder` (None if there is none or it is unreadable)."""
    try:
        data = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not isinstance(data.get("files"), list):
        return None
    return data


class OutputFolder:
    """A claimed, locked output folder; write files with `staging()`."""

    def __init__(self, path: Path, option: str, command: str, overwrite: bool):
        self.path, self.option, self.command = path, option, command
        if path.exists() and not path.is_dir():
            raise _refuse(option, path, "a folder (this path is a file)")
        previous = read_marker(path) if path.is_dir() else None
        self.previous = [str(f) for f in previous["files"]] if previous else []
        # files of an earlier mixvi version (no marker): kept, listed as "earlier", never removed
        self.earlier = [str(f) for f in previous.get("earlier", [])] if previous else []
        foreign = first_foreign(path) if path.is_dir() else None
        if previous is None and foreign is None and path.is_dir():
            self.earlier = _files(path)
        if foreign is not None and not overwrite:
            raise _refuse(
                option,
                path,
                f"a new or empty folder, or one written by mixvi; it holds {foreign!r}, "
                "which no mixvi run wrote (choose another folder, or pass --overwrite to "
                "write mixvi's files beside it: mixvi never deletes a file it did not write)",
            )
        self.created: list[Path] = []
        self._lock_fd: int | None = None
        self.committed = False
        try:
            with deferred():  # a signal right after mkdir must still find what to remove
                self.created = _create_dirs(path, option)
            self._lock()
            self._probe()
        except BaseException:
            self.release()
            raise

    def _lock(self) -> None:
        with deferred():  # a signal before the lock is recorded would leave the lock file
            self._take_lock()

    def _take_lock(self) -> None:
        lock = self.path / LOCK
        while True:
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
            except OSError as err:
                raise _refuse(
                    self.option, self.path, f"a folder mixvi can write ({_reason(err)})"
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                try:
                    pid = os.read(fd, 32).decode(errors="replace").strip() or "?"
                finally:
                    os.close(fd)
                raise _refuse(
                    self.option,
                    self.path,
                    f"a folder no other mixvi run is writing (locked by process {pid})",
                ) from None
            try:  # the lock file may have been removed by its previous holder meanwhile
                same = os.fstat(fd).st_ino == os.stat(lock).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, str(os.getpid()).encode())
                self._lock_fd = fd
                return
            os.close(fd)

    def _probe(self) -> None:
        """Create and remove a file: catches read-only and virtual file systems before work."""
        probe = self.path / f"{STAGING}probe-{os.getpid()}"
        try:
            with deferred():  # a signal between create and unlink would leave the probe
                fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
                try:
                    os.write(fd, b"mixvi")
                finally:
                    os.close(fd)
                probe.unlink()
        except OSError as err:
            with suppress(OSError):
                probe.unlink()
            raise _refuse(
                self.option, self.path, f"a folder mixvi can write ({_reason(err)})"
            ) from None

    @contextmanager
    def staging(self) -> Iterator[Path]:
        """A fresh folder to write into; on normal exit its files are committed."""
        tmp = Path(os.path.join(self.path, f"{STAGING}{os.getpid()}-{os.urandom(4).hex()}"))
        made = False
        try:
            # a signal right after mkdir must still find the folder to remove: the mkdir is a
            # deferred section inside the try whose finally removes it
            with deferred():
                try:
                    tmp.mkdir()
                except OSError as err:
                    raise _refuse(
                        self.option, self.path, f"a folder mixvi can write ({_reason(err)})"
                    ) from None
                made = True
            try:
                yield tmp
            except OSError as err:  # the disk or the file-size limit ran out while writing
                if err.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                    raise
                raise _refuse(
                    self.option, self.path, f"a folder with room for the results ({_reason(err)})"
                ) from None
            with deferred():
                self._commit(tmp)
        finally:
            if made:
                with deferred():
                    shutil.rmtree(tmp, ignore_errors=True)

    def _commit(self, tmp: Path) -> None:
        new = _files(tmp)
        stale = [f for f in self.previous if f not in set(new)]
        try:
            # first the marker lists old and new files (a kill in between leaves no file
            # unaccounted for), then the files, then the stale ones go, then the final marker
            self._write_marker(sorted({*self.previous, *new}), complete=False)
            for f in new:
                dest = self.path / f
                if dest.is_dir() and not dest.is_symlink():
                    raise _refuse(
                        self.option, self.path, f"a folder where {f!r} can be written (a folder)"
                    )
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(tmp / f, dest)
            for f in stale:
                p = self.path / f
                if p.is_file() or p.is_symlink():
                    with suppress(OSError):
                        p.unlink()
                    _prune(self.path, Path(f).parent)
            self.earlier = [f for f in self.earlier if f not in new and (self.path / f).exists()]
            self._write_marker(new, complete=True)
        except OSError as err:
            raise _refuse(
                self.option, self.path, f"a folder mixvi can write ({_reason(err)})"
            ) from None
        self.committed = True
        self.previous = new

    def _write_marker(self, files: list[str], complete: bool) -> None:
        marker = {
            "mixvi": _version(),
            "command": self.command,
            "time": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "complete": complete,
            "files": files,
        }
        if self.earlier:
            marker["earlier"] = self.earlier  # an earlier version's files, kept
        write_file(self.path / MARKER, json.dumps(marker, indent=2) + "\n")

    def release(self) -> None:
        """Unlock; remove the folders this run created if nothing was written into them."""
        with deferred():
            if self._lock_fd is not None:
                with suppress(OSError):
                    (self.path / LOCK).unlink()
                os.close(self._lock_fd)
                self._lock_fd = None
            if not self.committed:
                _remove_empty(self.created)


@contextmanager
def output_folder(
    path: str | Path, option: str = "--out", command: str | None = None, overwrite: bool = False
) -> Iterator[OutputFolder]:
    """Claim `path` for the whole `with` block (see the module rules); release at the end."""
    try:
        folder = OutputFolder(Path(path), option, command or _command_line(), overwrite)
    except (OSError, ValueError) as err:  # a path the OS cannot even look at
        raise _refuse(option, Path(path), f"a usable folder path ({_why(err)})") from None
    try:
        yield folder
    finally:
        folder.release()


def _command_line() -> str:
    return " ".join(["mixvi", *sys.argv[1:]])


class OutputFile:
    """A single file the user named, checked before work and replaced atomically."""

    def __init__(self, path: Path, option: str):
        if path.is_symlink():  # replace the file the link points to, not the link
            path = path.resolve()
        self.path, self.option = path, option
        if path.is_dir():
            raise _refuse(option, path, "a file path (this is a folder)")
        if path.exists() and not path.is_file():
            raise _refuse(option, path, "a regular file path (this is a device, pipe or socket)")
        self.created = _create_dirs(path.parent, option)
        self.written = False
        probe = path.parent / f"{STAGING}probe-{os.getpid()}"
        try:
            with deferred():  # a signal between create and unlink would leave the probe
                os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                probe.unlink()
        except OSError as err:
            with suppress(OSError):
                probe.unlink()
            _remove_empty(self.created)
            raise _refuse(option, path, f"a file mixvi can write ({_reason(err)})") from None

    def write(self, text: str) -> None:
        """Replace the file by `text` in one rename."""
        try:
            write_file(self.path, text)
        except OSError as err:
            raise _refuse(
                self.option, self.path, f"a file mixvi can write ({_reason(err)})"
            ) from None
        self.written = True

    def release(self) -> None:
        """Remove the folders created for the file if it was never written."""
        if not self.written:
            _remove_empty(self.created)


@contextmanager
def output_file(path: str | Path, option: str) -> Iterator[OutputFile]:
    """Claim the file `path` for the `with` block (parents created, writability checked)."""
    try:
        f = OutputFile(Path(path), option)
    except (OSError, ValueError) as err:  # a path the OS cannot even look at
        raise _refuse(option, Path(path), f"a usable file path ({_why(err)})") from None
    try:
        yield f
    finally:
        f.release()


def write_file(path: Path, text: str) -> None:
    """Write `text` to a temporary file beside `path` and rename it over `path` (user's
    umask; the temporary file is removed on any error or signal)."""
    tmp = path.parent / f"{STAGING}{os.getpid()}-{os.urandom(4).hex()}-{path.name}"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        with deferred():
            os.replace(tmp, path)
    finally:
        with deferred(), suppress(FileNotFoundError):
            tmp.unlink()


def jsonable(x):
    """`x` with numpy scalars and arrays turned into Python numbers and lists."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x
