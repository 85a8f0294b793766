"""Commands that draw nothing do not import matplotlib (its import is ~0.6 s of every
`mixvi validate`, and the CI tier starts hundreds of them): problems.output.plots imports
pyplot on first use."""

import subprocess
import sys

CODE = """
import sys
sys.argv = ["mixvi", "validate", "paper_two_body"]
from problems.commands.entry import run
try:
    run()
except SystemExit:
    pass
print("MPL" if "matplotlib.pyplot" in sys.modules else "NONE")
"""


def test_validate_does_not_import_pyplot():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "NONE", out.stdout


def test_pyplot_is_there_when_a_figure_is_drawn():
    from problems.output import plots

    plt = plots.pyplot()
    assert plt.get_backend().lower() == "agg"
