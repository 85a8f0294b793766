"""problems.commands.failures: exhausted resources map to exit 2 (1 for memory inside a
solve) with one line naming the resource; anything else stays an internal error (3)."""

from __future__ import annotations

import errno

import pytest

from problems.commands import failures


def _raised(err: BaseException) -> BaseException:
    try:
        raise err
    except BaseException as e:  # noqa: BLE001 - the traceback is what is under test
        return e


@pytest.mark.parametrize(
    "err, code, needle",
    [
        (MemoryError("Unable to allocate 8 GiB"), 2, "out of memory"),
        (RuntimeError("SUPERLU_MALLOC fails for buf in intCalloc()"), 2, "out of memory"),
        (ImportError("x.so: failed to map segment from shared object"), 2, "out of memory"),
        (OSError(errno.ENOSPC, "No space left on device"), 2, "no space left"),
        (OSError(errno.EDQUOT, "Disk quota exceeded"), 2, "no space left"),
        (OSError(errno.EFBIG, "File too large"), 2, "ulimit -f"),
        (failures.StdoutError(errno.EBADF, "stdout is closed"), 2, "writing stdout"),
        (RecursionError("maximum recursion depth exceeded"), 2, "nested too deeply"),
        (ValueError("a bug"), 3, "internal error"),
        (RuntimeError("another bug"), 3, "internal error"),
    ],
)
def test_exit_status_and_one_line(err, code, needle, capsys):
    assert failures.report(_raised(err)) == code
    text = capsys.readouterr().err
    assert needle in text and text.count("\n") == 1, text


def test_memory_inside_the_numerical_core_is_a_solve_that_ran(monkeypatch, capsys):
    """Frames under vi_core mark a solve that ran: exit 1 (as for not converged)."""
    monkeypatch.setattr(failures, "VI_CORE", __file__)
    assert failures.report(_raised(MemoryError())) == 1
    assert "during the solve" in capsys.readouterr().err


def test_mutation_a_superlu_failure_not_recognised_is_internal(monkeypatch, capsys):
    monkeypatch.setattr(failures, "is_memory", lambda err: isinstance(err, MemoryError))
    assert failures.report(_raised(RuntimeError("SUPERLU_MALLOC fails"))) == 3


def test_the_start_floor_grows_with_blas_threads(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    one = failures.START_BASE + failures.START_PER_THREAD
    monkeypatch.setattr(failures, "_limit", lambda which: one - 1)
    assert "ulimit -v" in failures.start_refusal()
    monkeypatch.setattr(failures, "_limit", lambda which: one)
    assert failures.start_refusal() is None
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "4")
    assert "4 BLAS thread(s)" in failures.start_refusal()
    monkeypatch.setattr(failures, "_limit", lambda which: None)
    assert failures.start_refusal() is None


@pytest.mark.parametrize("flushed", [True, False])
def test_each_finished_line_reaches_a_pipe_at_once(flushed, monkeypatch):
    """stdout a pipe (mpiexec's, `| tee`): a finished line is in the pipe when `print`
    returns, not when the run ends, so a run killed later (SIGKILL, the OOM killer) keeps its
    progress lines; a line still being written waits for its end. Mutation (`flushed`
    False): the wrapped stream's flush a no-op, as without the per-line flush, and the pipe
    stays empty."""
    import io
    import os

    r, w = os.pipe()
    os.set_blocking(r, False)
    inner = io.TextIOWrapper(open(w, "wb"), encoding="utf-8")  # block-buffered, as a pipe
    try:
        if not flushed:
            monkeypatch.setattr(inner, "flush", lambda: None)
        out = failures.GuardedStdout(inner)
        out.write("level 0 ")
        with pytest.raises(BlockingIOError):
            os.read(r, 100)
        out.write("done\n")
        if flushed:
            assert os.read(r, 100) == b"level 0 done\n"
        else:
            with pytest.raises(BlockingIOError):
                os.read(r, 100)
    finally:
        monkeypatch.undo()
        inner.close()
        os.close(r)
