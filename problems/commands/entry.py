"""The `mixvi` console script: SIGINT/SIGTERM are handled before the command line's heavy
imports (NumPy, SciPy, cvxpy, matplotlib take a second or more; `main` imports them when a
command runs, inside its own handling of failures and signals), so a Ctrl-C at any moment
ends with one line and exit status 130, never a traceback. An address-space limit too small
for those imports is refused before them, and an import that fails for lack of memory is
reported as such (`failures`), both with exit status 2. After an interruption (exit status
130 or 143, its clean-up done) the process ends at once (`signals.finish`)."""

from __future__ import annotations

import sys

from problems.output import signals


def run() -> int:
    """Install the signal handlers, then import and run `main`."""
    from . import failures

    refusal = failures.start_refusal()
    if refusal is not None:
        print(refusal, file=sys.stderr)
        return 2
    signals.install()
    try:
        from .main import main  # light: a command's heavy imports happen when it runs
    except KeyboardInterrupt as sig:
        name = str(sig) if isinstance(sig, signals.Interrupted) else "SIGINT"
        print(f"mixvi: interrupted by {name}", file=sys.stderr)
        return sig.exit_status if isinstance(sig, signals.Interrupted) else 130
    except Exception as err:  # an import that failed for lack of memory, or a bug
        return failures.report(err, "--debug" in sys.argv)
    status = main()
    if status in (130, 143):  # interrupted, its clean-up done: no interpreter tear-down
        signals.finish(status)
    signals.command_done()
    return status


if __name__ == "__main__":
    sys.exit(run())
