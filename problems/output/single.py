"""A single output file of a run (`problems.output.files` states the rules): mixvi's
signature at its start (`signature`, `written_by_mixvi`), checked before work, staged beside its
target and renamed over it at the commit (`OutputFile`)."""

from __future__ import annotations

import json
import os
import re
import sys
from contextlib import suppress
from pathlib import Path

from problems.errors import SceneError

from .paths import (
    STAGING,
    clear_stale,
    create_dirs,
    overwrite_hint,
    probe,
    refuse,
    remove_empty,
    unwritable,
    version,
)
from .signals import deferred

# the start of every single file mixvi writes (`_signed`): JSON's first key, or SVG's comment
SIGNED = re.compile(
    rb'\A(?:\{\s*"written_by":\s*"mixvi |(?:<\?xml[^>]{0,200}\?>\s*)?<!-- written_by: mixvi )'
)


def command_line() -> str:
    """This process's command line as `mixvi ARGS` (what a run marker and a signature record)."""
    return " ".join(["mixvi", *sys.argv[1:]])


def signature() -> str:
    """What mixvi's single files start with after their format's opening: "mixvi VERSION"."""
    return f"mixvi {version()}"


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
        data = {"written_by": f"{signature()} ({command_line()})", **content}
        return json.dumps(data, indent=2) + "\n"
    comment = f"<!-- written_by: {signature()} -->\n"
    head, sep, rest = content.partition("?>")
    if content.startswith("<?xml") and sep:
        return head + sep + "\n" + comment + rest.lstrip("\n")
    return comment + content


class OutputFile:
    """A single file of a run, checked before work, staged by `write` beside its target and
    renamed over it when the run's outputs are committed (`Claim`)."""

    def __init__(self, path: Path, option: str, kind: str, overwrite: bool):
        if path.is_symlink():  # replace the file the link points to, not the link
            path = path.resolve()
        self.path, self.option, self.kind = path, option, kind
        if path.is_dir():
            raise refuse(option, path, "a file path (this is a folder)")
        if path.exists() and not path.is_file():
            raise refuse(option, path, "a regular file path (this is a device, pipe or socket)")
        if path.exists() and not overwrite and not written_by_mixvi(path):
            raise refuse(
                option,
                path,
                "a new file or one mixvi wrote; this file exists and mixvi did not write it "
                f"(choose another name, or pass {overwrite_hint(option)} to replace it)",
            )
        self.created = create_dirs(path.parent, option)
        self.written = False
        self.staged: Path | None = None
        pids = clear_stale(path.parent, path.name)
        self.note = (
            f"{path}: removed temporary files of a run that ended without cleaning up "
            f"(process {', '.join(map(str, pids))}, no longer running), going on"
            if pids
            else None
        )
        try:
            probe(path.parent, option, path, "file")
        except SceneError:
            remove_empty(self.created)
            raise

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
            raise unwritable(self.option, self.path, err, "file") from None

    def _commit(self) -> None:
        if self.staged is None:
            return
        try:
            os.replace(self.staged, self.path)
        except OSError as err:
            raise unwritable(self.option, self.path, err, "file") from None
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
            remove_empty(self.created)
