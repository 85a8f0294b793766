"""`mixvi` whose stdout reader has left (`mixvi scenes | head -1`): a quiet end with exit
status 141 (128 + SIGPIPE), not an internal error."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

MIXVI = str(Path(sys.executable).with_name("mixvi"))


@pytest.mark.parametrize("argv", [["scenes"], ["validate", "signorini"]])
def test_a_reader_that_left_is_no_error(tmp_path, argv):
    """The pipe's reading end is closed before the child writes (no race with the reader):
    its first write of stdout breaks. Without the handler: exit 3, 'internal error'."""
    read, write = os.pipe()
    os.close(read)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    try:
        r = subprocess.run(
            [MIXVI, *argv], env=env, cwd=tmp_path, stdout=write, stderr=subprocess.PIPE,
            text=True, timeout=300,
        )  # fmt: skip
    finally:
        os.close(write)
    assert (r.returncode, r.stderr) == (141, "")
