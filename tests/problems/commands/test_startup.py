"""`mixvi --help` stays light: importing the command line and printing its help load none of
the heavy libraries (the time itself is a benchmark: benchmarks/bench_cli_startup.py)."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("numpy", "scipy", "cvxpy", "pydantic", "matplotlib", "clarabel", "meshio", "gmsh")

PROBE = """
import sys
{code}
heavy = {heavy!r}
print(",".join(sorted({{m.split(".")[0] for m in sys.modules}} & set(heavy))))
"""

HELP = """
import contextlib, io
from problems.commands.main import main
try:
    with contextlib.redirect_stdout(io.StringIO()):
        main(["--help"])
except SystemExit:
    pass
"""


def heavy_imports(code: str) -> list[str]:
    """The HEAVY packages in sys.modules after running `code` in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(code=code, heavy=HEAVY)],
        capture_output=True,
        text=True,
        check=True,
    )
    last = out.stdout.rstrip("\n").rsplit("\n", 1)[-1]
    return [m for m in last.split(",") if m]


def test_the_entry_point_and_help_import_nothing_heavy():
    assert heavy_imports("import problems.commands.entry, problems.commands.main") == []
    assert heavy_imports(HELP) == []


def test_mutation_a_heavy_import_is_seen():
    """The check fails where main would import a heavy package at the top (NumPy here: the
    cheapest of them to import)."""
    assert heavy_imports("import problems.commands.main; import numpy") == ["numpy"]
