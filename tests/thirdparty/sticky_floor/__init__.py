"""A third-party mixvi plug-in (contract v2), used to show that every command works for a
plug-in mixvi does not know: a membrane on a sticky floor, −Δu + λ = f on (0, 1)², u = 0 on
the boundary, |λ| ≤ g with λ = g sign(u) where u ≠ 0 (an ℓ¹ obstacle; docs/plugins.md)."""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fem import assembly, meshing
from fem.io import write_vtu
from problems.plugins.contract import ExtremeRow, Sweep, expect, read_head, read_solver
from problems.plugins.transfer import nodal_reference_errors
from vi_core import Box, MixedVI

CONTRACT = 2
NAME = "sticky_floor"
DESCRIPTION = "membrane on a sticky floor: −Δu = f − λ, |λ| ≤ g (third-party test plug-in)"
SCENE = str(Path(__file__).with_name("sticky_floor.toml"))
SWEEP = Sweep("sticky.g", "floor strength g [N/m²]", factors=(2.0, 1.0, 0.5))
NORMS = ("h1", "l2")


@dataclass
class Model:
    vi: MixedVI
    level: int
    mesh: object
    free: np.ndarray  # (n_free,) interior nodes
    options: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    @property
    def dofs(self):
        return {"u": self.vi.n, "multiplier": self.vi.m}

    def full(self, u):
        x = np.zeros(self.mesh.n_nodes)
        x[self.free] = u
        return x


def build(scene, level=None):
    root = scene.root()
    default_level = read_head(root, NAME)
    level = default_level if level is None else level
    t = root.table("sticky")
    n = t.integer("cells", 8, lo=1) * 2**level
    f, g = t.field("load", 1), t.number("g", lo=0.0)
    t.finish()
    options = read_solver(root)
    root.finish()
    mesh = meshing.rectangle((0.0, 1.0), (0.0, 1.0), (n, n), "triangle")
    free = np.flatnonzero(np.all((mesh.points > 0) & (mesh.points < 1), axis=1))
    K = assembly.stiffness_matrix(mesh)[free][:, free]
    D = assembly.volume_load(mesh, 1.0, 1)[free]  # (n_free,) ∫φᵢ
    vi = MixedVI(
        A=K,
        B=sp.diags(D),
        f=assembly.volume_load(mesh, f, 1)[free],
        Lambda=Box(-g, g, size=free.size),
    )
    return Model(vi, level, mesh, free, options)


def _stuck(model, sol):
    return np.abs(sol.u) <= 1e-12 * np.abs(sol.u).max(initial=1e-300)  # (n_free,)


def postprocess(model, sol, outdir):
    write_vtu(outdir / "sticky.vtu", model.mesh, {"u": model.full(sol.u)})
    return {"stuck_nodes": int(_stuck(model, sol).sum()), "files": ["sticky.vtu"]}


def mesh_size(model):
    return model.mesh.h


def reference_errors(model, sol, ref, ref_sol):
    return nodal_reference_errors(model.mesh, model.full(sol.u), ref.mesh, ref.full(ref_sol.u))


def _counts(model, sol):
    return {"stuck": int(_stuck(model, sol).sum()), "nodes": int(model.free.size)}


def extremes():
    return [
        ExtremeRow(
            "no floor (g = 0)", SCENE, ["sticky.g=0.0"], 0, None, [expect(_counts, stuck=0)]
        ),
        ExtremeRow(
            "glued (g × 1e3)", SCENE, ["sticky.g=4000.0"], 0, None, [expect(_counts, stuck="> 0")]
        ),
    ]
