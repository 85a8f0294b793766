"""An output folder of a run (`problems.output.files` states the rules): claimed, locked,
written through a staging folder and committed with its run marker; whose files are mixvi's
(`first_foreign`, `read_marker`)."""

from __future__ import annotations

import datetime
import errno
import fcntl
import json
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from .paths import (
    LOCK,
    MARKER,
    STAGING,
    clear_stale,
    create_dirs,
    files_under,
    identity,
    iter_files,
    overwrite_hint,
    probe,
    prune,
    reason,
    refuse,
    remove_empty,
    unwritable,
    version,
    write_file,
)
from .signals import deferred

# an unmarked folder whose files all end like this, with one of LEGACY_NAMES among them, was
# written by an earlier mixvi version (before the marker existed)
LEGACY_SUFFIXES = (".json", ".vtu", ".png")
LEGACY_NAMES = ("summary.json", "study.json", "extremes.json", "fig_5_4.png")


def first_foreign(folder: Path) -> str | None:
    """A file in `folder` that no mixvi run wrote (None: every file is mixvi's).

    With a marker, the files it lists are mixvi's; without one, the folder is an earlier
    mixvi version's output if every file ends in LEGACY_SUFFIXES and one is in LEGACY_NAMES.
    Stops at the first foreign file (a hostile target such as / is not walked through).
    """
    marker = read_marker(folder)
    listed = {str(f) for f in [*marker["files"], *marker.get("earlier", [])]} if marker else None
    first, legacy_name = None, False
    for f in iter_files(folder):
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


def _stale_note(path: Path, lock_pid: str | None, pids: list[int], incomplete: bool) -> str | None:
    """The one line that says what a killed run left in `path` and that it was cleared."""
    if lock_pid is None and not pids:
        return None
    who = sorted({*pids, *([int(lock_pid)] if lock_pid and lock_pid.isdigit() else [])})
    procs = ", ".join(map(str, who)) or "?"
    left = " and ".join(
        [*(["its lock"] if lock_pid is not None else []), *(["its staged files"] if pids else [])]
    )
    cut = "; its commit had not finished" if incomplete else ""
    return (
        f"{path}: a run that ended without cleaning up (process {procs}, no longer running) "
        f"left {left}{cut}; removed them (mixvi's own), going on"
    )


class OutputFolder:
    """A claimed, locked output folder; write files with `staging()`.

    inputs: the (device, inode) of every input of the run: never replaced or removed here."""

    def __init__(
        self,
        path: Path,
        option: str,
        command: str,
        overwrite: bool,
        inputs: frozenset[tuple[int, int]] = frozenset(),
    ):
        self.path, self.option, self.command, self.inputs = path, option, command, inputs
        self.note: str | None = None  # what a killed run left here (`_stale_note`)
        if path.exists() and not path.is_dir():
            raise refuse(option, path, "a folder (this path is a file)")
        previous = read_marker(path) if path.is_dir() else None
        self.previous = [str(f) for f in previous["files"]] if previous else []
        # files of an earlier mixvi version (no marker): kept, listed as "earlier", never removed
        self.earlier = [str(f) for f in previous.get("earlier", [])] if previous else []
        foreign = first_foreign(path) if path.is_dir() else None
        if previous is None and foreign is None and path.is_dir():
            self.earlier = files_under(path)
        if foreign is not None and not overwrite:
            raise refuse(
                option,
                path,
                f"a new or empty folder, or one written by mixvi; it holds {foreign!r}, "
                f"which no mixvi run wrote (choose another folder, or pass "
                f"{overwrite_hint(option)} to write mixvi's files beside it: mixvi never "
                "deletes a file it did not write)",
            )
        self.created: list[Path] = []
        self._lock_fd: int | None = None
        self.committed = False
        try:
            with deferred():  # a signal right after mkdir must still find what to remove
                self.created = create_dirs(path, option)
            stale_lock = self._lock()
            # we hold the lock: staging folders here are of runs that were killed
            incomplete = previous is not None and previous.get("complete") is False
            self.note = _stale_note(path, stale_lock, clear_stale(path), incomplete)
            probe(self.path, option, path)
        except BaseException:
            self.release()
            raise

    def _lock(self) -> str | None:
        """Take the folder's lock; the process id a stale lock file held (None: none)."""
        with deferred():  # a signal before the lock is recorded would leave the lock file
            return self._take_lock()

    def _take_lock(self) -> str | None:
        lock = self.path / LOCK
        while True:
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
            except OSError as err:
                raise unwritable(self.option, self.path, err) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                try:
                    pid = os.read(fd, 32).decode(errors="replace").strip() or "?"
                finally:
                    os.close(fd)
                raise refuse(
                    self.option,
                    self.path,
                    f"a folder no other mixvi run is writing (locked by process {pid})",
                ) from None
            try:  # the lock file may have been removed by its previous holder meanwhile
                same = os.fstat(fd).st_ino == os.stat(lock).st_ino
            except FileNotFoundError:
                same = False
            if same:
                # a holder unlinks the lock file before it lets go of it: a lock file that
                # still names a process, yet whose flock was free, is a killed run's
                old = os.pread(fd, 32, 0).decode(errors="replace").strip()
                os.ftruncate(fd, 0)
                os.write(fd, str(os.getpid()).encode())
                self._lock_fd = fd
                return old or None
            os.close(fd)

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
                    raise unwritable(self.option, self.path, err) from None
                made = True
            try:
                yield tmp
            except OSError as err:  # the disk or the file-size limit ran out while writing
                if err.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                    raise
                raise refuse(
                    self.option, self.path, f"a folder with room for the results ({reason(err)})"
                ) from None
            with deferred():
                self._commit(tmp)
        finally:
            if made:
                with deferred():
                    shutil.rmtree(tmp, ignore_errors=True)

    def _commit(self, tmp: Path) -> None:
        new = files_under(tmp)
        stale = [f for f in self.previous if f not in set(new)]
        for f in new:  # an input of this run (inside the folder) is never replaced
            if identity(self.path / f) in self.inputs:
                raise refuse(
                    self.option,
                    self.path,
                    f"a folder where mixvi's {f!r} does not replace an input of this run",
                )
        stale = [f for f in stale if identity(self.path / f) not in self.inputs]
        try:
            # first the marker lists old and new files (a kill in between leaves no file
            # unaccounted for), then the files, then the stale ones go, then the final marker
            self._write_marker(sorted({*self.previous, *new}), complete=False)
            for f in new:
                dest = self.path / f
                if dest.is_dir() and not dest.is_symlink():
                    raise refuse(
                        self.option, self.path, f"a folder where {f!r} can be written (a folder)"
                    )
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(tmp / f, dest)
            for f in stale:
                p = self.path / f
                if p.is_file() or p.is_symlink():
                    with suppress(OSError):
                        p.unlink()
                    prune(self.path, Path(f).parent)
            self.earlier = [f for f in self.earlier if f not in new and (self.path / f).exists()]
            self._write_marker(new, complete=True)
        except OSError as err:
            raise unwritable(self.option, self.path, err) from None
        self.committed = True
        self.previous = new

    def _write_marker(self, files: list[str], complete: bool) -> None:
        marker = {
            "mixvi": version(),
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
                remove_empty(self.created)
