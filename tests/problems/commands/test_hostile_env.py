"""`mixvi` under a hostile but sane environment (what a user's or CI machine may legitimately
have): C locale, a 20-column terminal width, TERM=dumb, progress bars disabled, no HOME, a
TMPDIR with a space in it, umask 077, one and eight OpenMP threads, a varied hash seed, no
MPLBACKEND, and a working directory outside the repository."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

MIXVI = str(Path(sys.executable).with_name("mixvi"))


def hostile_env(tmp: Path, threads: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "MPLBACKEND")}
    (tmp / "tmp dir").mkdir()
    env.update(
        LANG="C", LC_ALL="C", COLUMNS="20", TERM="dumb", TQDM_DISABLE="1",
        TMPDIR=str(tmp / "tmp dir"), OMP_NUM_THREADS=threads, PYTHONHASHSEED=threads,
    )  # fmt: skip
    return env


@pytest.mark.parametrize("threads", ["1", "8"])
def test_solve_and_validate_in_a_hostile_environment(tmp_path, threads):
    env = hostile_env(tmp_path, threads)
    work = tmp_path / "a folder"
    work.mkdir()

    def run(*argv: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [MIXVI, *argv], env=env, cwd=work, capture_output=True, text=True, timeout=600,
            preexec_fn=lambda: os.umask(0o077),
        )  # fmt: skip

    r = run("solve", "signorini", "--level", "1", "--out", "out put")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    summary = json.loads((work / "out put" / "summary.json").read_text())
    assert summary["converged"]
    assert "converged" in r.stdout
    r = run("validate", "signorini", "--set", "bodies.nowhere=1")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
