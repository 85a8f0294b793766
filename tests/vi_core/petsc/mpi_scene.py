"""Run under mpiexec by the tests: solve scenes with the petsc engine on every rank; rank 0
saves each field of u (displacement, potential), λ, the contact states and the residual of each
scene to an .npz.

    mpiexec -n P python -m tests.vi_core.petsc.mpi_scene SCENE LEVEL LINEAR OUT.npz [MUTATION]
    mpiexec -n P python -m tests.vi_core.petsc.mpi_scene --many OUTDIR LINEAR SCENE:LEVEL ...
        [--mutation MUTATION]        (one launch for many scenes: OUTDIR/SCENE.npz each)
"""

from __future__ import annotations

import inspect
import re
import sys
from pathlib import Path

import numpy as np

import problems.pipeline as pipeline
from problems.commands import engine
from problems.pipeline.load_path import solve_path


def solved(scene: str, level: int, linear_solver: str, name: str = "serial") -> dict:
    """Each field of u ("u:displacement", "u:potential", ...), λ ("lam"), the contact states,
    the Newton steps, the residual and the engine's record of `scene` at `level` solved on
    engine `name`. A scene with a load path is solved step by step as `mixvi solve` does: u,
    λ, the states and the Newton steps of every step, concatenated; the residual and records
    are the last step's."""
    eng = engine.start(name)
    loaded = pipeline.load(scene)
    steps: list[tuple] = []
    with engine.running(eng):
        if loaded.spec.load_path is None:
            run = pipeline.solve(loaded, level, linear_solver=linear_solver)
            steps.append((run.model, run.solution))
            converged = run.solution.converged
        else:
            path = solve_path(
                loaded,
                level,
                linear_solver=linear_solver,
                on_step=lambda s: steps.append((s.model, s.solution)),
            )
            converged = path.converged and len(path.steps) == len(steps)
    fields: dict[str, list] = {}
    for model, sol in steps:
        state = (
            loaded.plugin.contact_state(model, sol)
            if hasattr(loaded.plugin, "contact_state") and getattr(model, "contact", 1) is not None
            else {}
        )
        masks = model.vi.fields or {"all": np.ones(sol.u.shape, bool)}
        for key, val in [
            *((f"u:{f}", sol.u[mask]) for f, mask in masks.items()),
            ("lam", sol.lam),
            ("state", np.asarray(state.get("state", []), dtype=str)),
            ("iterations", np.array([sol.iterations])),
        ]:
            fields.setdefault(key, []).append(val)
    sol = steps[-1][1]
    return {
        **{key: np.concatenate(vals) for key, vals in fields.items()},
        "residual": sol.residual,
        "converged": converged,
        "steps": len(steps),
        "ranks": sol.info.get("ranks", 1),
        "engine": sol.info.get("engine", "serial"),
        "krylov": np.asarray(sol.info.get("krylov_iterations") or [], dtype=int),
        "fallbacks": len(sol.info.get("fallback") or []),
        "layout": str(sol.info.get("layout", "")),  # the linear solve's (`layout.chosen`)
        # PCFIELDSPLIT's blocks, in the fields' order: rows, near-null space dimension, block
        # size
        "blocks": np.array(list((sol.info.get("fieldsplit") or {}).values()), dtype=int),
        "rank": eng.rank,
    }


# faults injected into the source of a module of vi_core/petsc: name → (module, pattern,
# replacement)
SOURCE_FAULTS = {
    # the W term of the owned slave rows Dᵀ(W D^{-T} A_S + J B) with its sign flipped (the J B
    # term's sign is invisible in 2D: J is 0 or 1 there and its rows' right-hand side 0)
    "slave_sign": ("newton", r"Dt @ \(W @ (\w+)\.X\)", r"Dt @ (-W @ \1.X)"),
    # the states read the achieved residual only, not the GMRES step's accuracy
    # (`vi_core.states.solution_thresholds`): hertz's node on the symmetry axis reads "slip"
    "no_accuracy": ("newton", r"if solver\.accuracy\(\) is not None:", "if False:"),
    # A u at the answer not gathered at the end of the solve: the post-processing rank 0 runs
    # alone (a unilateral law's force scale, `contact_state`) waits on a collective forever
    "no_kept_product": ("newton", r"\n    vi\.matvec\(sol\.u\)", "\n    pass"),
    # the moved rows' columns left as unknowns, not the layout's PETSc rows (`Layout.moved`)
    "columns_unmapped": ("layout", r"\n        block\.indices = self\.new\[.*\n", "\n"),
    # the right-hand side in the order of its pieces [fixed rows; slave rows], not the
    # layout's rows' (a permutation applied where its inverse belongs)
    "rhs_order": (
        "newton",
        r"np\.argsort\(np\.searchsorted\(self\.rows, (.*)\)\)",
        r"np.searchsorted(self.rows, \1)",
    ),
    # the displacement's index set of PCFIELDSPLIT left at block size 1 (`ksp.node_block`)
    "no_node_block": (
        "ksp",
        r"index\.setBlockSize\(self\._block_size\(name, rows\.size\)\)",
        "None",
    ),
    # the balanced layout's groups split by unknowns, not nodes (`layout.node_groups`)
    "node_cut": ("layout", r"nodes=node_groups\(g, fields, per_node or \{\}\)", "nodes=None"),
    # each field's index set of PCFIELDSPLIT given the other fields' rows
    "fieldsplit_swapped": (
        "ksp",
        r"self\.layout\.field_rows\(mask\)",
        "self.layout.field_rows(~mask)",
    ),
}


def _mutate(name: str) -> None:
    """Inject a fault the tests must see (mutation tests): "fail_rank_1" raises a RuntimeError
    in rank 1's Newton loop only; "host_one_rank" makes `Engine.on_host` return this rank's
    value alone (the memory guard counts one rank per host); "local_gather" gathers only this
    rank's owned entries of each new iterate (the others stay 0: the off-rank entries
    dropped); a SOURCE_FAULTS name rewrites that module's source (ValueError if the pattern
    is not there once: the mutation must then be updated, not skipped), the names the other
    modules imported from it bound again."""
    from vi_core import petsc as vi_petsc
    from vi_core.petsc import ksp, layout, newton, runtime

    if name == "fail_rank_1":  # an internal error on rank 1 alone, in its first Newton loop

        def failing(*args, **kw):
            if runtime.comm_rank_size()[0] == 1:
                raise RuntimeError("injected on rank 1")
            return solve(*args, **kw)

        solve = newton.solve_ssn_petsc
        vi_petsc.solve_ssn_petsc = failing
    elif name == "host_one_rank":  # the memory guard counts this rank alone on its host

        def mine_only(self, value):
            return [value]

        engine.Engine.on_host = mine_only
    elif name == "local_gather":

        def gather(self, index, local, size):
            out = np.zeros(size)
            out[index] = local
            return out

        runtime.Reductions.gather = gather
    elif name in SOURCE_FAULTS:
        where, pattern, new = SOURCE_FAULTS[name]
        module = {"newton": newton, "layout": layout, "ksp": ksp}[where]
        src, count = re.subn(pattern, new, inspect.getsource(module))
        if count != 1:
            raise ValueError(f"mutation {name}: {pattern!r} found {count} times in {where}.py")
        exec(compile(src, module.__file__, "exec"), vars(module))
        for other in (newton, ksp):  # `from .layout import Layout`, `from .ksp import ...`
            for key in vars(other).keys() & vars(module).keys():
                if getattr(vars(module)[key], "__module__", "") == module.__name__:
                    setattr(other, key, vars(module)[key])
        vi_petsc.solve_ssn_petsc = newton.solve_ssn_petsc
    elif name:
        raise ValueError(f"unknown mutation {name!r}")


def main(argv: list[str]) -> int:
    if argv[0] == "--many":
        mutation = argv[argv.index("--mutation") + 1] if "--mutation" in argv else ""
        argv = argv[: argv.index("--mutation")] if mutation else argv
        _, outdir, linear_solver, *cases = argv
        _mutate(mutation)
        for case in cases:
            scene, level = case.split(":")
            got = solved(scene, int(level), linear_solver, "petsc")
            if got.pop("rank") == 0:
                np.savez(Path(outdir) / f"{scene}.npz", **got)
        return 0
    scene, level, linear_solver, out, *mutation = argv
    _mutate(mutation[0] if mutation else "")
    got = solved(scene, int(level), linear_solver, "petsc")
    if got.pop("rank") == 0:
        np.savez(out, **got)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
