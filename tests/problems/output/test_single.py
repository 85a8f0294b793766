"""problems.output.single: a file the OS will not let mixvi write is refused with the reason
(as root the read-only folder of test_files.py is writable, so the OS error is injected)."""

import errno
import os

import pytest

from problems.errors import SceneError
from problems.output import single
from problems.output.files import output_folder


def _read_only_below(root, monkeypatch) -> None:
    """os.open (what single.py and folder.py open with) refuses every path below `root` as
    a read-only file system would."""
    real_open = os.open

    def refusing(path, *args, **kwargs):
        if str(path).startswith(str(root)):
            raise OSError(errno.EROFS, "read-only")
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing)


def test_unwritable_file_is_refused_with_the_reason(tmp_path, monkeypatch):
    _read_only_below(tmp_path, monkeypatch)
    with pytest.raises(SceneError) as err:
        single.OutputFile(tmp_path / "out.json", "--out", "json", overwrite=False)
    assert "a file mixvi can write (read-only file system)" in str(err.value)
    assert not list(tmp_path.iterdir())  # nothing left behind


def test_unwritable_folder_is_refused_with_the_reason(tmp_path, monkeypatch):
    """An output folder the OS will not let mixvi write (the lock's open refused): the
    refusal names the reason, and a user's file already in the folder is left as it was."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("the user's")
    _read_only_below(out, monkeypatch)
    with pytest.raises(SceneError) as err, output_folder(out, overwrite=True):
        raise AssertionError("the body must not run")
    assert "a folder mixvi can write (read-only file system)" in str(err.value)
    assert [p.name for p in out.iterdir()] == ["mine.txt"]
    assert (out / "mine.txt").read_text() == "the user's"
