"""Long work shows a progress bar on a terminal, and nothing of it in a pipe or a log file."""

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

MIXVI = str(Path(sys.executable).parent / "mixvi")


def _on_a_terminal(argv, cwd) -> str:
    """Run `mixvi argv` with stdout and stderr on a pseudo-terminal of 100 columns, as on a
    machine so fast that every step ends within tqdm's display interval (TQDM_MININTERVAL):
    the bar's last state must still be shown (it once was only when a step took > 0.1 s)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
    env = {**os.environ, "TQDM_MININTERVAL": "1000"}
    proc = subprocess.Popen([MIXVI, *argv], cwd=cwd, stdout=slave, stderr=slave, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=600) == 0
    os.close(master)
    return b"".join(chunks).decode(errors="replace")


@pytest.mark.parametrize(
    ("argv", "bar"),
    [
        (["solve", "rigid_foundation", "--level", "2", "--out", "o"], "3/3"),
        (["figures", "rigid_foundation", "--level", "0", "--out", "o"], "3/3"),
        (["solve", "shear_strip_path", "--level", "0", "--out", "o"], "30/30"),
    ],
    ids=[
        "solve: levels of the nested iteration",
        "figures: one solve per value",
        "solve: steps of a load path",
    ],
)
def test_a_terminal_gets_a_progress_bar_and_a_pipe_does_not(tmp_path, argv, bar):
    (tmp_path / "tty").mkdir()
    (tmp_path / "pipe").mkdir()
    text = _on_a_terminal(argv, tmp_path / "tty")
    assert "solving" in text and bar in text
    run = subprocess.run([MIXVI, *argv], cwd=tmp_path / "pipe", capture_output=True, text=True)
    assert run.returncode == 0 and "solving" not in run.stderr and "%|" not in run.stderr
