"""Run under mpiexec by the tests: solve a scene with the petsc engine on every rank; rank 0
saves each field of u (displacement, potential), λ, the contact states and the residual to an
.npz.

    mpiexec -n P python -m tests.vi_core.petsc.mpi_scene SCENE LEVEL LINEAR OUT.npz [MUTATION]
"""

from __future__ import annotations

import sys

import numpy as np

import problems.pipeline as pipeline
from problems.commands import engine


def solved(scene: str, level: int, linear_solver: str, name: str = "serial") -> dict:
    """Each field of u ("u:displacement", "u:potential", ...), λ ("lam"), the contact states,
    the residual and the engine's record of `scene` at `level` solved on engine `name`."""
    eng = engine.start(name)
    loaded = pipeline.load(scene)
    with engine.running(eng):
        run = pipeline.solve(loaded, level, linear_solver=linear_solver)
    sol = run.solution
    state = pipeline.results(loaded, run).contact or {}
    fields = run.model.vi.fields or {"all": np.ones(sol.u.shape, bool)}
    return {
        **{f"u:{name}": sol.u[mask] for name, mask in fields.items()},
        "lam": sol.lam,
        "state": np.asarray(state.get("state", []), dtype=str),
        "residual": sol.residual,
        "converged": sol.converged,
        "ranks": sol.info.get("ranks", 1),
        "engine": sol.info.get("engine", "serial"),
        "rank": eng.rank,
    }


def _mutate(name: str) -> None:
    """Inject a fault the tests must see (mutation tests): "local_gather" gathers only this
    rank's owned entries of each new iterate (the others stay 0)."""
    from vi_core.petsc import runtime

    if name == "local_gather":

        def gather(self, index, local, size):
            out = np.zeros(size)
            out[index] = local
            return out

        runtime.Reductions.gather = gather
    elif name:
        raise ValueError(f"unknown mutation {name!r}")


def main(argv: list[str]) -> int:
    scene, level, linear_solver, out, *mutation = argv
    _mutate(mutation[0] if mutation else "")
    got = solved(scene, int(level), linear_solver, "petsc")
    if got.pop("rank") == 0:
        np.savez(out, **got)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
