"""Output folders and files: nothing of the user's is ever deleted, moved or replaced.

The rules, one mechanism (`claim`) for every output of every command: the folders of solve,
figures, study and extremes (`--out`), and the single files of check (`--json`) and bench
(`--out`, `--figure`):

- Before any work, all of a run's outputs are claimed together (`claim`): no two on one path
  or one inside another, none the same file as an input of the run (the scene file, the mesh
  files it names, bench's --scenes; symbolic and hard links followed), parents that are
  folders, creatable and writable (not under a regular file, not read-only, not a virtual file
  system); otherwise SceneError naming the option and path (exit 2, nothing run).
- A folder that exists and holds files which no run marker lists is refused (SceneError naming
  the folder and one such file) unless `overwrite`: then mixvi writes its files beside the
  others (replacing only files of the same names) and still deletes nothing it did not write.
  A folder without a marker whose files all carry names mixvi writes (an earlier mixvi version's
  output) counts as mixvi's. An input of the run inside the folder is never replaced or removed.
- A single file is mixvi's if it starts with mixvi's signature (JSON: a first key
  "written_by": "mixvi VERSION ..."; SVG: a comment `<!-- written_by: mixvi VERSION -->` after
  the XML declaration), which every single file mixvi writes carries. An existing file without
  it is refused unless `overwrite` (then it is replaced).
- A claimed folder is locked (`.mixvi-lock`, an flock holding the process id): a second run into
  it is refused. A lock file whose flock is free was left by a run that was killed (SIGKILL, a
  power cut): the next run says so in one line, removes the staging folders and temporary files
  of processes that no longer run (mixvi's own, by their names), and proceeds.
- Files are written into a staging folder inside the target (single files: a temporary file
  beside each) and committed at the end: each file renamed into place, the files the previous
  run listed and this one does not write again removed (nothing else), and the marker
  `.mixvi-run.json` (command, version, time, files) written last. The commit runs with signals
  deferred; on an error or a signal before it, the staged files are removed and every target
  is as it was. A run's single files are committed together.
- Folders and files get the user's umask.
"""

from __future__ import annotations

import datetime
import errno
import fcntl
import json
import os
import re
import shutil
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from problems.errors import SceneError

from .signals import deferred

MARKER = ".mixvi-run.json"
LOCK = ".mixvi-lock"
STAGING = ".mixvi-tmp-"  # prefix of staging folders and temporary files
# the names mixvi gives them: STAGING + pid + 8 hex digits (+ "-" + the target's name for a
# temporary file), or STAGING + "probe-" + pid; group 1 the pid, group 2 the target's name
STAGED = re.compile(r"\.mixvi-tmp-(?:probe-)?(\d+)(?:-[0-9a-f]{8}(?:-(.+))?)?")
# the start of every single file mixvi writes (`_signed`): JSON's first key, or SVG's comment
SIGNED = re.compile(
    rb'\A(?:\{\s*"written_by":\s*"mixvi |(?:<\?xml[^>]{0,200}\?>\s*)?<!-- written_by: mixvi )'
)
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


def _identity(path: Path) -> tuple[int, int] | None:
    """(device, inode) of the file at `path` (links followed), None if there is none."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def _running(pid: int) -> bool:
    """Whether a process `pid` exists (ours, or one we may not signal, counts)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _clear_stale(folder: Path, name: str | None = None) -> list[int]:
    """Remove the staging folders and temporary files in `folder` that runs which no longer
    run left behind (killed before their clean-up): entries named as mixvi names them
    (STAGED) whose process is gone; with `name`, only the temporary files of the target `name`
    (and probes). Returns the processes whose leftovers were removed."""
    pids = set()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    for e in entries:
        m = STAGED.fullmatch(e.name)
        probe = e.name.startswith(f"{STAGING}probe-")
        if m is None or (name is not None and not probe and m.group(2) != name):
            continue  # not mixvi's, or (beside a single file) not of this target
        pid = int(m.group(1))
        if _running(pid):
            continue
        with deferred(), suppress(OSError):
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path)
            else:
                os.unlink(e.path)
            pids.add(pid)
    return sorted(pids)


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
            stale_lock = self._lock()
            # we hold the lock: staging folders here are of runs that were killed
            incomplete = previous is not None and previous.get("complete") is False
            self.note = _stale_note(path, stale_lock, _clear_stale(path), incomplete)
            self._probe()
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
                # a holder unlinks the lock file before it lets go of it: a lock file that
                # still names a process, yet whose flock was free, is a killed run's
                old = os.pread(fd, 32, 0).decode(errors="replace").strip()
                os.ftruncate(fd, 0)
                os.write(fd, str(os.getpid()).encode())
                self._lock_fd = fd
                return old or None
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
        for f in new:  # an input of this run (inside the folder) is never replaced
            if _identity(self.path / f) in self.inputs:
                raise _refuse(
                    self.option,
                    self.path,
                    f"a folder where mixvi's {f!r} does not replace an input of this run",
                )
        stale = [f for f in stale if _identity(self.path / f) not in self.inputs]
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


def _command_line() -> str:
    return " ".join(["mixvi", *sys.argv[1:]])


def signature() -> str:
    """What mixvi's single files start with after their format's opening: "mixvi VERSION"."""
    return f"mixvi {_version()}"


def written_by_mixvi(path: Path) -> bool:
    """Whether the file at `path` starts with mixvi's signature (SIGNED)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError:
        return False
    return SIGNED.match(head) is not None


def _signed(content, kind: str) -> str:
    """The text of a single file of `kind` with mixvi's signature: JSON, a dict, whose first
    key becomes "written_by"; SVG, text, a comment after its XML declaration."""
    if kind == "json":
        data = {"written_by": f"{signature()} ({_command_line()})", **content}
        return json.dumps(data, indent=2) + "\n"
    comment = f"<!-- written_by: {signature()} -->\n"
    head, sep, rest = content.partition("?>")
    if content.startswith("<?xml") and sep:
        return head + sep + "\n" + comment + rest.lstrip("\n")
    return comment + content


@dataclass(frozen=True)
class Output:
    """One output of a run: a folder (`kind` "folder") or a single file of a format mixvi
    signs ("json", "svg"), named by the command-line `option` that gave it."""

    path: str | Path
    option: str
    kind: str = "folder"


class OutputFile:
    """A single file of a run, checked before work, staged by `write` beside its target and
    renamed over it when the run's outputs are committed (`Claim`)."""

    def __init__(self, path: Path, option: str, kind: str, overwrite: bool):
        if path.is_symlink():  # replace the file the link points to, not the link
            path = path.resolve()
        self.path, self.option, self.kind = path, option, kind
        if path.is_dir():
            raise _refuse(option, path, "a file path (this is a folder)")
        if path.exists() and not path.is_file():
            raise _refuse(option, path, "a regular file path (this is a device, pipe or socket)")
        if path.exists() and not overwrite and not written_by_mixvi(path):
            raise _refuse(
                option,
                path,
                "a new file or one mixvi wrote; this file exists and mixvi did not write it "
                "(choose another name, or pass --overwrite to replace it)",
            )
        self.created = _create_dirs(path.parent, option)
        self.written = False
        self.staged: Path | None = None
        pids = _clear_stale(path.parent, path.name)
        self.note = (
            f"{path}: removed temporary files of a run that ended without cleaning up "
            f"(process {', '.join(map(str, pids))}, no longer running), going on"
            if pids
            else None
        )
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

    def write(self, content) -> None:
        """Stage `content` (JSON: a dict; SVG: its text), signed (`_signed`), in a temporary
        file beside the target; the run's commit renames it over the target."""
        text = _signed(content, self.kind)
        self.discard()
        tmp = self.path.parent / f"{STAGING}{os.getpid()}-{os.urandom(4).hex()}-{self.path.name}"
        try:
            with deferred():  # recorded as soon as it exists: a signal then finds it
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
                self.staged = tmp
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
        except OSError as err:
            self.discard()
            raise _refuse(
                self.option, self.path, f"a file mixvi can write ({_reason(err)})"
            ) from None

    def _commit(self) -> None:
        if self.staged is None:
            return
        try:
            os.replace(self.staged, self.path)
        except OSError as err:
            raise _refuse(
                self.option, self.path, f"a file mixvi can write ({_reason(err)})"
            ) from None
        self.staged, self.written = None, True

    def discard(self) -> None:
        """Remove the staged file, if any (the target stays as it was)."""
        with deferred():
            if self.staged is not None:
                with suppress(FileNotFoundError):
                    self.staged.unlink()
                self.staged = None

    def release(self) -> None:
        """Drop what was not committed; remove the folders created for the file if it was
        never written."""
        self.discard()
        if not self.written:
            _remove_empty(self.created)


def _real(path: Path) -> Path:
    """The absolute path with every symbolic link of its existing part resolved."""
    return Path(os.path.realpath(path))


def _inside(a: Path, b: Path) -> bool:
    return a != b and b in a.parents


class Claim:
    """All outputs of one run, claimed together (module rules): `folder(option)` and
    `file(option)` give them; `commit()` renames the staged single files into place."""

    def __init__(
        self,
        outputs: Sequence[Output],
        inputs: Iterable[tuple[str, str | Path]],
        command: str,
        overwrite: bool,
    ):
        reals = []
        for o in outputs:
            try:
                reals.append(_real(Path(o.path)))
            except (OSError, ValueError) as err:
                raise _refuse(o.option, Path(o.path), f"a usable path ({_why(err)})") from None
        for i, (a, ra) in enumerate(zip(outputs, reals, strict=True)):
            for b, rb in zip(outputs[i + 1 :], reals[i + 1 :], strict=True):
                same = ra == rb or (_identity(ra) is not None and _identity(ra) == _identity(rb))
                if same or _inside(rb, ra) or _inside(ra, rb):
                    where = (
                        "the same path as"
                        if same
                        else "inside"
                        if _inside(rb, ra)
                        else "a folder holding"
                    )
                    raise _refuse(
                        b.option,
                        Path(b.path),
                        f"a path of its own ({b.option} would be {where} {a.option} {a.path})",
                    )
        ids = set()
        for what, path in inputs:
            ident = _identity(Path(path))
            if ident is None:
                continue
            ids.add(ident)
            real = _real(Path(path))
            for o, r in zip(outputs, reals, strict=True):
                if r == real or _identity(r) == ident:
                    raise _refuse(
                        o.option,
                        Path(o.path),
                        f"a path that is not an input of this run (it is {what} {path})",
                    )
        self.folders: dict[str, OutputFolder] = {}
        self.files: dict[str, OutputFile] = {}
        try:
            for o in outputs:
                path = Path(o.path)
                try:
                    if o.kind == "folder":
                        self.folders[o.option] = OutputFolder(
                            path, o.option, command, overwrite, frozenset(ids)
                        )
                    else:
                        self.files[o.option] = OutputFile(path, o.option, o.kind, overwrite)
                except (OSError, ValueError) as err:  # a path the OS cannot even look at
                    raise _refuse(o.option, path, f"a usable path ({_why(err)})") from None
        except BaseException:
            self.release()
            raise
        for t in [*self.folders.values(), *self.files.values()]:
            if t.note:
                print(f"mixvi: note: {t.note}", file=sys.stderr)

    def folder(self, option: str = "--out") -> OutputFolder:
        """The claimed folder of `option`."""
        return self.folders[option]

    def file(self, option: str) -> OutputFile:
        """The claimed single file of `option`."""
        return self.files[option]

    def commit(self) -> None:
        """Rename every staged single file into place, all with signals deferred."""
        with deferred():
            for f in self.files.values():
                f._commit()

    def release(self) -> None:
        """Unlock the folders, drop what was not committed, remove empty folders created."""
        with deferred():
            for t in [*self.folders.values(), *self.files.values()]:
                t.release()


@contextmanager
def claim(
    outputs: Sequence[Output],
    inputs: Iterable[tuple[str, str | Path]] = (),
    command: str | None = None,
    overwrite: bool = False,
) -> Iterator[Claim]:
    """Claim every output of a run for the `with` block (module rules); inputs: (what, path)
    of each file the run reads, e.g. ("the scene file", "rf.toml"). On normal exit the single
    files are committed; on an error or a signal nothing of them is left."""
    c = Claim(outputs, list(inputs), command or _command_line(), overwrite)
    try:
        yield c
        c.commit()
    finally:
        c.release()


@contextmanager
def output_folder(
    path: str | Path,
    option: str = "--out",
    command: str | None = None,
    overwrite: bool = False,
    inputs: Iterable[tuple[str, str | Path]] = (),
) -> Iterator[OutputFolder]:
    """`claim` of one folder: the claimed folder for the `with` block."""
    with claim([Output(path, option)], inputs, command, overwrite) as c:
        yield c.folder(option)


def write_file(path: Path, text: str) -> None:
    """Write `text` to a temporary file beside `path` and rename it over `path` (user's
    umask; the temporary file is removed on any error or signal). For mixvi's own
    bookkeeping (the marker); a run's outputs go through `claim`."""
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
