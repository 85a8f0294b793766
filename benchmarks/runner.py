"""One benchmark case in a fresh process (`in_child`), so that its CPU time, peak memory and
imports are its own: the runner every script of benchmarks/ that measures a case uses."""

from __future__ import annotations

import multiprocessing as mp
import time
from collections.abc import Callable


def in_child(target: Callable[..., None], args: tuple, timeout: float | None = None) -> dict | None:
    """Run target(*args, q) in a spawned process; the record it puts on the queue q, or None if
    it died without one or was killed after `timeout` seconds (None: no limit)."""
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=target, args=(*args, q), daemon=True)
    p.start()
    deadline = None if timeout is None else time.monotonic() + timeout
    while p.is_alive() and (deadline is None or time.monotonic() < deadline):
        p.join(0.2)
        if not q.empty():
            break
    out = q.get() if not q.empty() else None
    if p.is_alive() and out is None:
        p.kill()
    p.join()
    return out


def record(target: Callable[..., None], args: tuple) -> dict:
    """`in_child` without a time limit, for a case that must give its record: RuntimeError
    naming the case if the child died without one."""
    out = in_child(target, args)
    if out is None:
        raise RuntimeError(f"{target.__name__}{args} ended without a record (see its traceback)")
    return out
