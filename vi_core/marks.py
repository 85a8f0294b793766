"""A test hook: where the signal tests of the command line (tests/problems/commands/
test_signals.py) need to know that a solve is inside a long compiled call.

With the environment variable MIXVI_MARK set to a file path, `mark(what, n)` appends the line
`WHAT N` to that file just before the call starts: "splu N" before a SuperLU factorisation of
an N × N matrix, "amg N" before a pyamg set-up, "clarabel N" before a Clarabel solve (N its
unknowns). Unset (always, outside those tests), it does nothing but read the variable.
"""

from __future__ import annotations

import os

VARIABLE = "MIXVI_MARK"


def mark(what: str, n: int) -> None:
    """Append `what n` to the file named by MIXVI_MARK, if it is set."""
    path = os.environ.get(VARIABLE)
    if path:
        with open(path, "a") as f:
            f.write(f"{what} {n}\n")
