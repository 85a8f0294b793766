"""Exceptions → exit statuses and the one line a user reads: the single mapping of every
failure that is not a `SceneError` (bad input named by its field), whichever thread raised it.

Resources are bad input, not bugs (exit 2; 1 where a solve ran, as for a solve that did not
converge): memory exhausted (a `MemoryError`; SuperLU's "SUPERLU_MALLOC fails", a MemoryError
or a RuntimeError depending on where in SuperLU; a shared library that cannot be mapped), the
disk full, the file-size limit (`ulimit -f`), stdout full or closed. Each message names the
resource, the limit where one is set, and what to do. Anything else is an internal error (exit 3).

`report(err, debug)` prints the line and returns the status; `problems.commands.main.main` and
the entry point's import phase (`problems.commands.entry`) both use it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import importlib.util
import os
import resource
import stat
import sys
import traceback
from collections.abc import Callable
from typing import Any

from problems.output import signals

# errno values of a full disk (ENOSPC, EDQUOT: a quota) and of the file-size limit (EFBIG)
DISK_FULL = {errno.ENOSPC, errno.EDQUOT}
FILE_TOO_LARGE = {errno.EFBIG}
# frames under the numerical core's folder: a solve was running (located, not imported: the
# entry point reports failures of its heavy imports with this module)
_spec = importlib.util.find_spec("vi_core")
VI_CORE = os.path.join(list(_spec.submodule_search_locations)[0], "") if _spec else "\0"


class StdoutError(OSError):
    """Writing the command's standard output failed (full device, closed, I/O error)."""


def _limit(which: int) -> int | None:
    soft, _ = resource.getrlimit(which)
    return None if soft == resource.RLIM_INFINITY else soft


def _mib(n: int) -> str:
    return f"{n / 2**20:,.0f} MiB"


def memory_text() -> str:
    """What bounds the memory: the address-space limit if one is set, else the machine."""
    limit = _limit(resource.RLIMIT_AS)
    if limit is not None:
        return (
            f"the address-space limit (ulimit -v) is {_mib(limit)}: raise it, or ask for less "
            "(a lower --level)"
        )
    return "the machine's memory is exhausted: ask for less (a lower --level) or free memory"


def is_memory(err: BaseException) -> bool:
    """An allocation failure: MemoryError, or a library that could not be mapped for lack of
    address space (ImportError "failed to map segment" / "cannot allocate memory")."""
    if isinstance(err, MemoryError):
        return True
    text = str(err).lower()
    if isinstance(err, RuntimeError) and "malloc fails" in text:  # SuperLU's SUPERLU_MALLOC
        return True
    return isinstance(err, ImportError | OSError) and (
        "failed to map segment" in text
        or "cannot allocate memory" in text
        or getattr(err, "errno", None) == errno.ENOMEM
    )


def solve_ran(err: BaseException) -> bool:
    """Whether the failure happened inside the numerical core (vi_core): a solve ran."""
    tb = err.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename.startswith(VI_CORE):
            return True
        tb = tb.tb_next
    return False


def resource_message(err: BaseException) -> str | None:
    """The one line for an exhausted resource (without the 'mixvi: error: ' prefix), or None
    if `err` is not one."""
    if is_memory(err):
        first = str(err).splitlines()[0][:120] if str(err) else type(err).__name__
        where = "during the solve" if solve_ran(err) else "while building or writing"
        return f"out of memory {where} ({first}); {memory_text()}"
    if not isinstance(err, OSError):
        return None
    target = "stdout" if isinstance(err, StdoutError) else (err.filename or "an output file")
    if err.errno in DISK_FULL:
        what = "redirect stdout elsewhere" if target == "stdout" else "free space, or --out on "
        what += "" if target == "stdout" else "another file system"
        return f"writing {target}: no space left on the device: {what}"
    if err.errno in FILE_TOO_LARGE:
        limit = _limit(resource.RLIMIT_FSIZE)
        shown = f" of {limit:,} bytes" if limit is not None else ""
        return (
            f"writing {target}: the file-size limit (ulimit -f){shown} was reached: raise it "
            "(ulimit -f unlimited)"
        )
    if isinstance(err, StdoutError):
        return f"writing stdout: {err.strerror or err}: run with stdout open and writable"
    return None


# The address space (RLIMIT_AS) mixvi needs to start its numerical libraries: below it the
# imports fail in many ways, and OpenBLAS, unable to allocate a thread's buffer while it is
# loaded, retries forever inside C code, where no signal handler of Python runs (SIGTERM is
# then ignored). Measured with `mixvi solve signorini --level 0` under `ulimit -v`: it runs at
# 390 MiB with one BLAS thread (OPENBLAS_NUM_THREADS=1) and at 450 MiB with two; the floor
# adds a margin: START_BASE + START_PER_THREAD × BLAS threads.
START_BASE = 400 * 2**20
START_PER_THREAD = 64 * 2**20


def cores() -> int:
    """The cores this process may run on (its CPU affinity; os.cpu_count where unknown)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def blas_threads() -> int:
    """The threads OpenBLAS starts: its environment variables, else the usable cores (≤ 64)."""
    for var in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS"):
        text = os.environ.get(var, "").split(",")[0].strip()
        if text.isdigit() and int(text) > 0:
            return min(int(text), 64)
    return min(cores(), 64)


def start_refusal() -> str | None:
    """The one line refusing to start under an address-space limit below the floor the
    numerical libraries need (None if there is no limit or it suffices)."""
    limit = _limit(resource.RLIMIT_AS)
    if limit is None:
        return None
    threads = blas_threads()
    need = START_BASE + START_PER_THREAD * threads
    if limit >= need:
        return None
    return (
        f"mixvi: error: the address-space limit (ulimit -v) is {_mib(limit)}: mixvi needs at "
        f"least {_mib(need)} to start its numerical libraries with {threads} BLAS thread(s); "
        "raise the limit (or set OPENBLAS_NUM_THREADS=1 to need less)"
    )


def report(err: BaseException, debug: bool = False) -> int:
    """Print the one line for `err` (an exception that is not a SceneError) and return the
    exit status: 2 for an exhausted resource (1 if a solve ran: memory inside the numerical
    core), 3 for an internal error (with --debug the traceback first). An error that a signal
    caused (`signals.masked`: NumPy's initialisation turns SIGINT into an ImportError) is the
    interruption: one line, exit status 130 or 143."""
    sig = signals.masked(err)
    if sig is not None:
        _say(f"mixvi: interrupted by {sig}")
        return sig.exit_status
    if debug:
        traceback.print_exception(err)
    if isinstance(err, StdoutError) and sys.stdout is not None:
        with contextlib.suppress(OSError, ValueError):  # what is still buffered goes nowhere,
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # not to exit's flush
    msg = resource_message(err)
    if msg is not None:
        _say(f"mixvi: error: {msg}")
        return 1 if is_memory(err) and solve_ran(err) else 2
    if isinstance(err, RecursionError):
        _say(
            "mixvi: error: a value nested too deeply (RecursionError): scene values and --set "
            "values nested a few levels at most"
        )
        return 2
    what = f"{type(err).__name__}: {err}".splitlines()[0][:300]
    hint = "" if debug else "; run again with --debug for the traceback"
    _say(f"mixvi: internal error: {what}{hint}")
    return 3


def _say(line: str) -> None:
    """Print to stderr; stderr itself gone or full: nothing more can be said."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError, AttributeError):
        pass


class GuardedStdout:
    """sys.stdout as the commands see it while `guarded_stdout` is active: a failed write or
    flush raises StdoutError (so the message names stdout, not "an output file"); a reader
    that left still raises BrokenPipeError (exit 141); each finished line is flushed, as on a
    terminal, so a pipe or a file has it before the run ends (or is killed). Everything else
    is the wrapped stream's."""

    def __init__(self, inner):
        self._inner = inner
        self.written = 0  # bytes written through it (counted only for a regular file)
        try:  # the process's stdout a regular file: where writing starts, else None
            self._start = _file_offset() if inner.fileno() == 1 else None
        except (AttributeError, OSError, ValueError):  # io.StringIO, a closed stream
            self._start = None

    def write(self, text: str) -> int:
        if self._start is not None:
            self.written += len(text.encode(self._inner.encoding, self._inner.errors))
        n = _on_stdout(self._inner.write, text)
        if "\n" in text:  # each finished line out now, also into a pipe or a file (mpiexec's,
            _on_stdout(self._inner.flush)  # `| tee`): a run killed later keeps its lines
        return n

    def flush(self) -> None:
        _on_stdout(self._inner.flush)
        self.check_complete()

    def check_complete(self) -> None:
        """A regular file as stdout that holds fewer bytes than were written: a write was cut
        short by the file-size limit or a full disk, which Python's buffered writer may not
        report (measured: CPython 3.11 drops the rest of a partial write silently)."""
        if self._start is None:
            return
        end = _file_offset(self._start[1])
        if end is not None and end[0] - self._start[0] < self.written:
            limit = _limit(resource.RLIMIT_FSIZE)
            full = limit is not None and end[0] >= limit
            code = errno.EFBIG if full else errno.ENOSPC
            raise StdoutError(code, os.strerror(code))

    def __getattr__(self, name: str):
        return getattr(self._inner, name)


def _file_offset(append: bool | None = None) -> tuple[int, bool] | None:
    """(where the next write to stdout lands, opened for appending) if stdout is a regular
    file, else None."""
    try:
        if not stat.S_ISREG(os.fstat(1).st_mode):
            return None
        if append is None:
            append = bool(fcntl.fcntl(1, fcntl.F_GETFL) & os.O_APPEND)
        pos = os.fstat(1).st_size if append else os.lseek(1, 0, os.SEEK_CUR)
    except OSError:
        return None
    return pos, append


@contextlib.contextmanager
def guarded_stdout():
    """sys.stdout wrapped in GuardedStdout for the `with` block (restored after it); a closed
    stdout (`mixvi ... >&-`) is refused first: file descriptor 1 would be reused by the next
    file opened, and everything printed lost. On leaving, stdout is flushed inside the block,
    not at interpreter exit (where a failure prints 'Exception ignored', status 120)."""
    check_stdout()
    before = sys.stdout
    if not isinstance(before, GuardedStdout):
        sys.stdout = GuardedStdout(before)
    try:
        yield
        flush_stdout()
    finally:
        sys.stdout = before


def flush_stdout() -> None:
    """Flush stdout inside the command (not at interpreter exit, where a failure would be
    printed as 'Exception ignored' with status 120): StdoutError if it fails."""
    out = sys.stdout
    if out is not None:
        _on_stdout(out.flush)


def _on_stdout(call: Callable[..., Any], *args: Any) -> Any:
    """`call(*args)`, a write or flush of stdout: a failure raises StdoutError (so the message
    names stdout), a reader that left still BrokenPipeError (exit 141)."""
    try:
        return call(*args)
    except BrokenPipeError:
        raise
    except OSError as err:
        raise StdoutError(err.errno, err.strerror) from None


def check_stdout() -> None:
    """StdoutError if stdout is closed."""
    try:
        os.fstat(1)
    except OSError as err:
        raise StdoutError(errno.EBADF, "stdout is closed") from err
    if sys.stdout is None:
        raise StdoutError(errno.EBADF, "stdout is closed")
