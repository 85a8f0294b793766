"""SIGINT and SIGTERM as one exception, and sections that a signal may not cut in half.

`install()` (called once by the `mixvi` entry point) makes both signals raise `Interrupted`
in the main thread; the command line maps it to exit status 128 + signal number (130, 143).
Inside `deferred()` a signal is only recorded and raised when the section ends, so that a
commit of output files (a handful of renames) and the clean-up after an error always complete.

A signal that arrives while C code runs (a sparse factorisation) is acted on when control
returns to the interpreter: Python runs signal handlers between bytecodes.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """A SIGINT or SIGTERM received by a command (a KeyboardInterrupt, so `except Exception`
    does not swallow it)."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)

    @property
    def exit_status(self) -> int:
        """128 + the signal number: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


_depth = 0  # nesting of deferred() sections
_pending: list[int] = []


def _handler(signum: int, frame) -> None:
    if _depth > 0:
        _pending.append(signum)
        return
    raise Interrupted(signum)


def install() -> None:
    """Make SIGINT and SIGTERM raise `Interrupted` (main thread only; a no-op elsewhere)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for s in SIGNALS:
        signal.signal(s, _handler)


def ignore_in_child() -> None:
    """In a worker process: ignore SIGINT (the parent, which gets the same Ctrl-C, ends the
    worker) and die quietly on SIGTERM (the default action, no traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def deferred() -> Iterator[None]:
    """A section a signal cannot interrupt: a signal received inside is raised at its end."""
    global _depth
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0 and _pending:
            signum = _pending[0]
            _pending.clear()
            raise Interrupted(signum)
