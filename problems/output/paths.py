"""The file-system steps under every output of a run (`problems.output.files` states the
rules): the names of mixvi's bookkeeping and staging entries, folder creation with a clear
refusal, the OS errors in words, the clean-up of what a killed run left behind, and the atomic
write of mixvi's own bookkeeping files."""

from __future__ import annotations

import errno
import os
import re
import shutil
from collections.abc import Iterator
from contextlib import suppress
from pathlib import Path

from problems.errors import SceneError

from .signals import deferred

MARKER = ".mixvi-run.json"
LOCK = ".mixvi-lock"
STAGING = ".mixvi-tmp-"  # prefix of staging folders and temporary files
# the names mixvi gives them: STAGING + pid + 8 hex digits (+ "-" + the target's name for a
# temporary file), or STAGING + "probe-" + pid; group 1 the pid, group 2 the target's name
STAGED = re.compile(r"\.mixvi-tmp-(?:probe-)?(\d+)(?:-[0-9a-f]{8}(?:-(.+))?)?")


def version() -> str:
    """The installed mixvi's version ("unknown" outside an installation)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("mixvi")
    except PackageNotFoundError:
        return "unknown"


def refuse(option: str, path: Path, allowed: str) -> SceneError:
    """The refusal of the output `path` given by `option`, saying what is `allowed`."""
    return SceneError(option, str(path), allowed)


def unwritable(option: str, path: Path, err: OSError, what: str = "folder") -> SceneError:
    """The refusal of the output `path` given by `option` that the OS would not let mixvi
    write (`what`: "folder" or "file"), saying why (`reason`)."""
    return refuse(option, path, f"a {what} mixvi can write ({reason(err)})")


def probe(folder: Path, option: str, path: Path, what: str = "folder") -> None:
    """Create, write and remove a file in `folder`: catches read-only and virtual file systems
    before work (the refusal names the output `path` given by `option`, a `what`)."""
    probe = folder / f"{STAGING}probe-{os.getpid()}"
    made = False  # only a probe this call created is removed (never a file of that name)
    try:
        with deferred():  # a signal between create and unlink would leave the probe
            fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            made = True
            try:
                os.write(fd, b"mixvi")
            finally:
                os.close(fd)
            probe.unlink()
    except OSError as err:
        if made:
            with suppress(OSError):
                probe.unlink()
        raise unwritable(option, path, err, what) from None


def overwrite_hint(option: str) -> str:
    """How the caller that named its output `option` asks to overwrite: the command line's
    flag for an option (`--out`), the keyword for the Python API (`folder`)."""
    return "--overwrite" if option.startswith("-") else "overwrite=True"


def create_dirs(path: Path, option: str) -> list[Path]:
    """mkdir -p `path` (user's umask); the folders created, outermost first. SceneError if a
    parent is a file or a folder cannot be created."""
    missing = []
    p = path
    while not p.exists():
        if p.is_symlink():  # a dangling link: do not write through it
            raise refuse(option, path, f"a folder path; {p} is a broken symbolic link")
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise refuse(option, path, f"a folder path whose parents are folders; {p} is a file")
    created = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            if not d.is_dir():
                raise refuse(option, path, f"a folder path; {d} is a file") from None
            continue
        except OSError as err:
            remove_empty(created)
            raise refuse(
                option, path, f"a folder mixvi can create ({reason(err)} at {d})"
            ) from None
        created.append(d)
    return created


def reason(err: OSError) -> str:
    """An OS error in words, with what to do where there is something to do."""
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


def why(err: Exception) -> str:
    """`reason` of an OS error, the message of any other."""
    return reason(err) if isinstance(err, OSError) else str(err)


def remove_empty(created: list[Path]) -> None:
    """Remove the folders this run created (innermost first) if they are still empty."""
    for d in reversed(created):
        with suppress(OSError):
            d.rmdir()


def prune(root: Path, rel: Path) -> None:
    """Remove the folder `root/rel` and its parents below `root` while they are empty (the
    subfolders of a run's files, e.g. levels/1/, once those files are gone); a folder that
    holds anything stays."""
    while rel.parts:
        try:
            (root / rel).rmdir()
        except OSError:  # not empty (or already gone): stop
            return
        rel = rel.parent


def iter_files(root: Path) -> Iterator[str]:
    """Relative paths of the non-folder entries under `root`, top level first (mixvi's own
    bookkeeping and staging entries left out)."""
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(STAGING))
        rel = Path(dirpath).relative_to(root)
        for f in sorted(filenames):
            if f in (MARKER, LOCK) or f.startswith(STAGING):
                continue
            yield str(rel / f) if str(rel) != "." else f


def files_under(root: Path) -> list[str]:
    """`iter_files` as a list."""
    return list(iter_files(root))


def identity(path: Path) -> tuple[int, int] | None:
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


def clear_stale(folder: Path, name: str | None = None) -> list[int]:
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


def write_file(path: Path, text: str, replace: bool = True) -> None:
    """Write `text` to a temporary file beside `path` (user's umask) and rename it over
    `path`, or without `replace` hard-link it to `path`: a new file whole or not at all,
    never replacing one (FileExistsError if the name is taken); the temporary file is removed
    on any error or signal. For mixvi's own bookkeeping (the marker) and `mixvi new`'s
    template; a run's outputs go through `claim`."""
    tmp = path.parent / f"{STAGING}{os.getpid()}-{os.urandom(4).hex()}-{path.name}"
    made = False  # the finally removes only a file this call created
    try:
        with deferred():  # recorded as soon as it exists: the finally removes it
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            made = True
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        with deferred():
            (os.replace if replace else os.link)(tmp, path)
    finally:
        if made:
            with deferred(), suppress(FileNotFoundError):
                tmp.unlink()
