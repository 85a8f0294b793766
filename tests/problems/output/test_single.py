"""problems.output.single: a file the OS will not let mixvi write is refused with the reason
(as root the read-only folder of test_files.py is writable, so the OS error is injected)."""

import errno
import os

import pytest

from problems.errors import SceneError
from problems.output import single


def test_unwritable_file_is_refused_with_the_reason(tmp_path, monkeypatch):
    real_open = os.open

    def refusing(path, *args, **kwargs):
        if str(path).startswith(str(tmp_path)):
            raise OSError(errno.EROFS, "read-only")
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(single.os, "open", refusing)
    with pytest.raises(SceneError) as err:
        single.OutputFile(tmp_path / "out.json", "--out", "json", overwrite=False)
    assert "a file mixvi can write (read-only file system)" in str(err.value)
    assert not list(tmp_path.iterdir())  # nothing left behind
