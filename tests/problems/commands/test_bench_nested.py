"""`mixvi bench`'s nested solve is `mixvi solve`'s (`pipeline.nested_iteration`): the same
Newton steps per level and the same answer; its time is every level's warm start and solve,
the models' construction excluded; no coarse model is alive while the finest level is solved."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from problems import pipeline
from problems.commands import bench

LEVEL, TOL = 2, 1e-10


@pytest.mark.parametrize("linear_solver", ["amg", "splu"])
def test_bench_solves_as_mixvi_solve(linear_solver):
    loaded = pipeline.load("paper_two_body")
    run = pipeline.solve(loaded, LEVEL, tol=TOL, linear_solver=linear_solver)
    model, sol, _, _, iters = bench._nested_ssn(
        loaded.plugin, loaded.scene, LEVEL, TOL, linear_solver
    )
    assert model.level == LEVEL and sol.converged
    assert iters == [r["iterations"] for r in run.nested]
    for a, b in ((sol.u, run.solution.u), (sol.lam, run.solution.lam)):
        assert np.linalg.norm(a - b) <= 1e-12 * np.linalg.norm(b)
    # the finest level did start from the coarser one: fewer Newton steps than from cold
    cold = pipeline.solve(loaded, LEVEL, tol=TOL, cold=True, linear_solver=linear_solver)
    assert iters[-1] < cold.solution.iterations


def test_bench_times_warm_starts_and_solves_not_builds(monkeypatch):
    """A clock that moves only inside fakes of the slow parts: each build takes 1000 s, each
    warm start 1 s, each solve 10 s. The nested solve of level 2 is two warm starts and three
    solves: 32 s on both clocks, whatever the machine."""
    loaded = pipeline.load("paper_two_body")
    plugin, now = loaded.plugin, np.zeros(2)  # (2,) the fake wall-clock and CPU seconds
    calls = {"build": 0, "warm_start": 0, "solve": 0}

    def slow(name, seconds, real):
        def fake(*args, **kwargs):
            out = real(*args, **kwargs)
            now[:] += seconds
            calls[name] += 1
            return out

        return fake

    monkeypatch.setattr(bench, "_clocks", lambda: now.copy())
    monkeypatch.setattr(plugin, "build", slow("build", 1000.0, plugin.build))
    monkeypatch.setattr(plugin, "warm_start", slow("warm_start", 1.0, plugin.warm_start))
    monkeypatch.setattr(pipeline, "solve_model", slow("solve", 10.0, pipeline.solve_model))
    _, sol, wall, cpu, iters = bench._nested_ssn(plugin, loaded.scene, LEVEL, TOL, "splu")
    assert sol.converged and len(iters) == LEVEL + 1
    assert calls == {"build": LEVEL + 1, "warm_start": LEVEL, "solve": LEVEL + 1}
    assert wall == cpu == 1.0 * LEVEL + 10.0 * (LEVEL + 1)


def test_no_coarse_model_alive_while_bench_solves_the_finest_level(monkeypatch):
    loaded = pipeline.load("paper_two_body")
    plugin, coarse, alive = loaded.plugin, [], []
    build, solve_model = plugin.build, pipeline.solve_model

    def recording_build(scene, level):
        model = build(scene, level)
        if level < LEVEL:
            coarse.append(weakref.ref(model))
        return model

    def checking_solve(plugin, model, **kwargs):
        if model.level == LEVEL:
            alive.append([ref() is not None for ref in coarse])
        return solve_model(plugin, model, **kwargs)

    monkeypatch.setattr(plugin, "build", recording_build)
    monkeypatch.setattr(pipeline, "solve_model", checking_solve)
    bench._nested_ssn(plugin, loaded.scene, LEVEL, TOL, "splu")
    assert alive == [[False] * LEVEL]


def test_without_warm_start_bench_solves_the_finest_level_alone_as_mixvi_solve():
    """The obstacle plug-in has no `warm_start`: `mixvi solve` solves the finest level from a
    cold start, and so does bench (no coarse level solved and timed)."""
    loaded = pipeline.load("obstacle")
    assert not hasattr(loaded.plugin, "warm_start")
    run = pipeline.solve(loaded, LEVEL, tol=TOL)
    model, sol, _, _, iters = bench._nested_ssn(loaded.plugin, loaded.scene, LEVEL, TOL)
    assert model.level == LEVEL and run.nested == [] and sol.converged
    assert iters == [run.solution.iterations]
    for a, b in ((sol.u, run.solution.u), (sol.lam, run.solution.lam)):
        assert np.linalg.norm(a - b) <= 1e-12 * np.linalg.norm(b)
