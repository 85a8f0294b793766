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

import os
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .folder import OutputFolder
from .paths import identity, refuse, why
from .signals import deferred
from .single import OutputFile, command_line


@dataclass(frozen=True)
class Output:
    """One output of a run: a folder (`kind` "folder") or a single file of a format mixvi
    signs ("json", "svg"), named by the command-line `option` that gave it."""

    path: str | Path
    option: str
    kind: str = "folder"


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
                raise refuse(o.option, Path(o.path), f"a usable path ({why(err)})") from None
        for i, (a, ra) in enumerate(zip(outputs, reals, strict=True)):
            for b, rb in zip(outputs[i + 1 :], reals[i + 1 :], strict=True):
                same = ra == rb or (identity(ra) is not None and identity(ra) == identity(rb))
                if same or _inside(rb, ra) or _inside(ra, rb):
                    where = (
                        "the same path as"
                        if same
                        else "inside"
                        if _inside(rb, ra)
                        else "a folder holding"
                    )
                    raise refuse(
                        b.option,
                        Path(b.path),
                        f"a path of its own ({b.option} would be {where} {a.option} {a.path})",
                    )
        ids = set()
        for what, path in inputs:
            ident = identity(Path(path))
            if ident is None:
                continue
            ids.add(ident)
            real = _real(Path(path))
            for o, r in zip(outputs, reals, strict=True):
                if r == real or identity(r) == ident:
                    raise refuse(
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
                    raise refuse(o.option, path, f"a usable path ({why(err)})") from None
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
    c = Claim(outputs, list(inputs), command or command_line(), overwrite)
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
