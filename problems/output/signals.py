"""SIGINT and SIGTERM as one exception, sections that a signal may not cut in half, and
numerical work that a signal can interrupt even while it runs inside compiled code.

`install()` (called once by the `mixvi` entry point) makes both signals raise `Interrupted`
in the main thread; the command line maps it to exit status 128 + signal number (130, 143).
Inside `deferred()` a signal is only recorded and raised when the section ends, so that a
commit of output files (a handful of renames) and the clean-up after an error always complete.

Python runs a signal handler only in the main thread, between bytecodes: while the main
thread is inside one long C call (a SuperLU factorisation of a large matrix can take minutes)
a Ctrl-C does nothing until the call returns. So the commands run their numerical work through
`interruptible(fn, ...)`: `fn` runs in a worker thread while the main thread waits in a loop
of short queue reads, which return to the interpreter at least every POLL seconds (a signal
also wakes the read at once). On a signal the main thread raises `Interrupted` where it waits,
runs today's clean-up (the `finally` blocks of the output folder: staging folder removed, lock
released), prints its one line, and the process ends with `os._exit` (`exit_status`): a thread
stuck in C cannot be cancelled, and an interpreter shut-down around it is not worth the risk.
The worker never touches files itself: the callbacks that write (a coarse level's results, a
load step's files) are wrapped with `in_main` and run in the main thread, in order, while the
worker waits for them, so the clean-up never races a write (a worker left behind by a signal
that reaches its next write gets the interruption instead), and a commit (renames under
`deferred`, in the main thread) is never cut by the exit. Exceptions raised in the worker
(SceneError, MemoryError, any other) are raised again, unchanged, in the main thread.

Measured (docs/benchmarks.md, "Interrupting a command"): SuperLU (scipy's splu), Clarabel and
the compiled kernels of pyamg's set-up release the GIL, so the main thread acts on a signal
within ~0.1 s while they run (the longest wait of the main thread on the paper scene at levels
3–4: 0.1–0.45 s, for any solver); PARDISO (pypardiso) calls it through ctypes, which releases
the GIL too. The alternative, the work in a subprocess, would have to pickle the built model
and its solution back to the parent; this needs no copy at all. Solve times are unchanged (the
same BLAS thread pools: OpenBLAS's thread count is process-wide, and the linear solvers set
their own `threadpool_limits` inside the work). The Python API (`problems.solve_scene`) never
calls `install()` and so runs in the caller's thread, as before: `interruptible` is a plain call
unless the handlers are installed and it is called in the main thread.
"""

from __future__ import annotations

import os
import queue
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

SIGNALS = (signal.SIGINT, signal.SIGTERM)
POLL = 0.1  # longest time [s] the waiting main thread stays away from the interpreter

T = TypeVar("T")


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
_installed = False
_calls: queue.SimpleQueue | None = None  # the running worker's requests to the main thread
_abandoned: list[threading.Thread] = []  # workers still inside their work after a signal
_raised: list[int] = []  # the signals the handler has raised as Interrupted
_one_rank = False  # this process is one rank of several of an MPI run (`one_rank_of_several`)
_alone = False  # this rank stopped on an error of its own mid-solve (`ends_alone`)


def _handler(signum: int, frame) -> None:
    if _depth > 0:
        _pending.append(signum)
        return
    _raised.append(signum)
    raise Interrupted(signum)


def masked(err: BaseException) -> Interrupted | None:
    """The interruption behind `err`, an ordinary exception, if a signal caused it: a signal
    raised inside the initialisation of a compiled module is turned into an ImportError by the
    import machinery (NumPy's `PyCapsule_Import could not import module "datetime"`), so
    `err` after a raised `Interrupted` is that interruption, not a failure of its own."""
    seen: BaseException | None = err
    while seen is not None:
        if isinstance(seen, Interrupted):
            return seen
        seen = seen.__cause__ or seen.__context__
    return Interrupted(_raised[0]) if _raised else None


REDELIVER = 0.005  # s after a swallowed interruption before it is raised again


def _unraisable(info: Any, default: Callable[[Any], None] = sys.__unraisablehook__) -> None:
    """`sys.unraisablehook` while the handlers are installed: an `Interrupted` that Python
    could not raise (the handler ran inside a weakref callback, a `__del__` or a GC callback,
    whose exceptions Python prints as "Exception ignored in …" and drops: a Ctrl-C during the
    start-up imports lands in importlib's module-lock callback) is delivered again a moment
    later, once the main thread is back in ordinary code (`_thread.interrupt_main` from a
    timer thread); anything else goes to Python's own hook."""
    if not isinstance(info.exc_value, Interrupted):
        default(info)
        return
    import _thread

    signum = info.exc_value.signum
    timer = threading.Timer(REDELIVER, _thread.interrupt_main, (signum,))
    timer.daemon = True
    timer.start()


def install() -> None:
    """Make SIGINT and SIGTERM raise `Interrupted` (main thread only; a no-op elsewhere), also
    where Python would drop the exception (`_unraisable`)."""
    global _installed
    if threading.current_thread() is not threading.main_thread():
        return
    for s in SIGNALS:
        signal.signal(s, _handler)
    sys.unraisablehook = _unraisable
    _installed = True
    _raised.clear()  # a run's own signals only (the API and tests call main more than once)


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


class _Call:
    """A call the worker asks the main thread to make; the worker waits for its outcome."""

    def __init__(self, fn: Callable[..., Any], args: tuple, kwargs: dict):
        self.fn, self.args, self.kwargs = fn, args, kwargs
        self.done = threading.Event()
        self.value: Any = None
        self.error: BaseException | None = None

    def run(self) -> None:
        """In the main thread. An exception goes back to the worker; a signal (Interrupted)
        propagates here and leaves the worker waiting (it is abandoned)."""
        try:
            self.value = self.fn(*self.args, **self.kwargs)
        except Exception as err:
            self.error = err
        self.done.set()


def in_main(fn: Callable[..., T]) -> Callable[..., T]:
    """`fn` made to run in the main thread when called from inside `interruptible` (the worker
    waits for it and gets its result or exception); called anywhere else, a plain call. For
    the callbacks of a solve that write files."""

    def call(*args: Any, **kwargs: Any) -> T:
        calls = _calls
        me = threading.current_thread()
        if me in _abandoned:  # the main thread has cleaned up and is leaving: a write now
            # would come after (or race) the clean-up, e.g. make the staging folder again
            raise Interrupted(_raised[0] if _raised else signal.SIGINT)
        if calls is None or me is threading.main_thread():
            return fn(*args, **kwargs)
        c = _Call(fn, args, kwargs)
        calls.put(c)
        c.done.wait()
        if c.error is not None:
            raise c.error
        return c.value

    return call


def interruptible(fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
    """fn(*args, **kwargs), run so that SIGINT/SIGTERM are acted on at once even while it is
    inside compiled code: in a worker thread while the main thread waits (see the module
    docstring). A plain call unless `install()` was called and this is the main thread (the
    Python API), or inside another `interruptible`."""
    global _calls
    if not _installed or _calls is not None:
        return fn(*args, **kwargs)
    if threading.current_thread() is not threading.main_thread():
        return fn(*args, **kwargs)
    calls: queue.SimpleQueue = queue.SimpleQueue()
    outcome: dict[str, Any] = {}

    def work() -> None:
        try:
            outcome["value"] = fn(*args, **kwargs)
        except BaseException as err:  # raised again in the main thread
            outcome["error"] = err
        finally:
            calls.put(None)

    worker = threading.Thread(target=work, name="mixvi-work", daemon=True)
    _calls = calls
    try:
        worker.start()
        while True:
            try:
                item = calls.get(timeout=POLL)  # returns to the interpreter: handlers run
            except queue.Empty:
                continue
            if item is None:
                break
            item.run()
    except BaseException:
        if worker.is_alive():
            _abandoned.append(worker)
        raise
    finally:
        _calls = None
    worker.join()
    if "error" in outcome:
        err = outcome.pop("error")
        raise err
    return outcome["value"]


def _worker_running() -> bool:
    """Whether a worker left behind by an interruption is still inside its work."""
    return any(t.is_alive() for t in _abandoned)


def _exit_now(status: int) -> None:
    """Flush the standard streams and end the process with `status` (`os._exit`)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


def exit_if_abandoned(status: int) -> None:
    """After an interruption: if a worker is still inside its work (compiled code, which
    cannot be cancelled), flush the standard streams and end the process now with `status`
    (`os._exit`: no interpreter shut-down around a thread that still runs); else return."""
    if _worker_running():
        _exit_now(status)


def one_rank_of_several() -> None:
    """Mark this process as one rank of an MPI run of several (`mixvi solve --engine petsc`
    under mpiexec): `finish` then ends it without the exit handlers. An interruption ends one
    rank alone while the others may still be inside the solve, and the handlers petsc4py and
    mpi4py registered are collective (PETSc's garbage clean-up duplicates a communicator, then
    MPI_Finalize): the rank would wait in them forever for ranks that wait for it in the
    solve, and mpiexec, which ends the others once one rank has ended with a non-zero status,
    would never see it end."""
    global _one_rank
    _one_rank = True


def ends_alone() -> None:
    """This process, if one rank of several, stops on an error of its own while the others may
    still be inside the solve (a refusal only rank 0 meets: its output folder full or over
    the file-size limit halfway through a load path). `exit_if_alone` then ends it once its
    clean-up has run, without the exit handlers, which are collective and would wait forever
    for those ranks; mpiexec ends them once this one has ended with a non-zero status."""
    global _alone
    _alone = _one_rank


def exit_if_alone(status: int) -> None:
    """After the clean-up of an error: if this rank stops alone (`ends_alone`), flush the
    standard streams and end the process now with `status` (`os._exit`); else return."""
    if _alone:
        _exit_now(status)


def command_done() -> None:
    """The command has returned, its clean-up done. One rank of several (`one_rank_of_several`)
    then waits in its exit handlers, inside compiled code that runs no Python signal handler,
    for the others (rank 0 may still be writing the results): SIGINT and SIGTERM get their
    default action back, so a signal there ends this rank at once and mpiexec ends the others
    (rank 0's clean-up leaves its folder as it was), where it would raise `Interrupted` inside
    an exit handler once they end (a traceback, the run going on). A no-op for one process."""
    if _one_rank and threading.current_thread() is threading.main_thread():
        for s in SIGNALS:
            signal.signal(s, signal.SIG_DFL)


def finish(status: int) -> None:
    """End the process now with `status` after an interruption whose clean-up has run (the
    `finally` blocks the signal went through): the exit handlers (`atexit`) unless a worker is
    still inside its work, the standard streams flushed, then `os._exit` — without the
    interpreter's tear-down of every module and object, which took 1.1–1.4 s of the 1.2–1.5 s
    from a SIGTERM to the exit of `mixvi bench` on a loaded 2-core machine (its child, the
    solve, was already gone after 0.1 s). One rank of several (`one_rank_of_several`): no exit
    handlers either (they are collective)."""
    if not _worker_running() and not _one_rank:
        import atexit

        atexit._run_exitfuncs()
    _exit_now(status)
