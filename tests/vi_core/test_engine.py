"""vi_core.engine: method="ssn" runs the Newton loop an engine installs, inside its block only
(and after an exception in it), the serial loop elsewhere, in any thread."""

from __future__ import annotations

import threading

import pytest

import vi_core
from vi_core import engine
from vi_core.ssn import solve_ssn
from vi_core.testing import random_vi


def test_installed_loop_runs_inside_the_block_only():
    vi = random_vi(0, n=12, m=6)
    seen = []

    def loop(v, tol, **options):
        seen.append((v, tol))
        return solve_ssn(v, tol=tol, **options)

    with engine.using(loop):
        assert engine.ssn_loop() is loop
        sol = vi_core.solve(vi, "ssn", tol=1e-9)
        got = []  # a worker thread (mixvi solve's) sees it too
        t = threading.Thread(target=lambda: got.append(engine.ssn_loop()))
        t.start()
        t.join()
        assert got == [loop]
    assert seen == [(vi, 1e-9)] and sol.converged
    assert engine.ssn_loop() is solve_ssn
    vi_core.solve(vi, "ssn")
    assert len(seen) == 1


def test_restored_after_an_exception():
    with pytest.raises(RuntimeError), engine.using(lambda *a, **k: None):
        raise RuntimeError("boom")
    assert engine.ssn_loop() is solve_ssn
