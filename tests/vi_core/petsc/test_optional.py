"""petsc4py and mpi4py are optional: without them vi_core.petsc and `mixvi solve` import, and
`--engine petsc` is refused with exit status 2, naming the option and the install path."""

from __future__ import annotations

import subprocess
import sys

import pytest

# petsc4py and mpi4py made unimportable (None in sys.modules: ImportError on import)
WITHOUT = "import sys; sys.modules['petsc4py'] = None; sys.modules['mpi4py'] = None; "


def run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", WITHOUT + code], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("guard", [True, pytest.param(False, marks=pytest.mark.slow)])
def test_engine_petsc_refused_without_petsc4py(tmp_path, guard):
    """One process (~8 s under load): vi_core.petsc and mixvi solve import, `available` says
    False, --engine petsc is refused with status 2 and nothing is written. Mutation
    (guard=False): `available` made to say True; the run then fails on import (status 3)
    instead of the clear refusal."""
    patch = "import vi_core.petsc as p; assert not p.available(); "
    if not guard:
        patch += "p.available = lambda: True; "
    code = (
        patch + "from problems.commands.main import main; "
        f"sys.exit(main(['solve', 'manufactured', '--level', '0', '--engine', 'petsc', "
        f"'--out', {str(tmp_path / 'o')!r}]))"
    )
    done = run(code)
    refused = done.returncode == 2 and "--engine" in done.stderr and "petsc4py" in done.stderr
    assert refused == guard, (done.returncode, done.stderr[-500:])
    assert not (tmp_path / "o").exists()
