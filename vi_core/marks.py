"""A test hook: where the signal tests of the command line (tests/problems/commands/
test_signals.py) need to know that a solve is inside a long compiled call.

With the environment variable MIXVI_MARK set to a file path, `mark(what, n)` appends the line
`WHAT N THREAD` to that file just before the call starts: "splu N main" before a SuperLU
factorisation of an N × N matrix made in the main thread, "amg N mixvi-work" before a pyamg
set-up made in another thread (its name), "clarabel N ..." before a Clarabel solve (N its
unknowns). The thread tells whether the main thread is free to act on a signal meanwhile
(problems.output.signals). Unset (always, outside those tests), it does nothing but read the
variable.
"""

from __future__ import annotations

import os
import threading

VARIABLE = "MIXVI_MARK"


def mark(what: str, n: int) -> None:
    """Append `what n thread` to the file named by MIXVI_MARK, if it is set."""
    path = os.environ.get(VARIABLE)
    if path:
        thread = threading.current_thread()
        name = "main" if thread is threading.main_thread() else thread.name.replace(" ", "_")
        with open(path, "a") as f:
            f.write(f"{what} {n} {name}\n")
