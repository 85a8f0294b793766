"""Owned-rows assembly (`fem.assembly`, ``rows=``; issue 33, docs/distributed.md): a rank
assembling only the cells touching its owned rows gets those rows of the whole matrix bit for
bit (values, column indices and their order, explicit zeros included) and no other row, for
every form, 2D and 3D, on any row partition; the other ranks' rows are never computed."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import example, given, settings
from hypothesis import strategies as st

import fem.assembly as asm

from .test_assembly import C_BTO, E_BTO, KAPPA_BTO, PIEZO, distorted, wavy_box

MESHES = {
    "quad": lambda: distorted("quad", (5, 4)),
    "triangle": lambda: distorted("triangle", (5, 4)),
    "hexahedron": lambda: wavy_box("hexahedron", 2),
    "tetra": lambda: wavy_box("tetra", 2),
}


def _materials(dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (C_BTO, E_BTO, KAPPA_BTO) if dim == 2 else (PIEZO.C, PIEZO.e, PIEZO.kappa)


def _forms(mesh, rows_u, rows_phi):
    """(name, whole matrix, its owned-rows assembly) of each form, the rows given per field."""
    C, e, kappa = _materials(mesh.points.shape[1])
    rows = np.concatenate([rows_u, rows_phi])
    return [
        ("K", asm.elasticity_matrix(mesh, C), asm.elasticity_matrix(mesh, C, rows=rows_u)),
        ("G", asm.coupling_matrix(mesh, e), asm.coupling_matrix(mesh, e, rows=rows_phi)),
        (
            "P",
            asm.permittivity_matrix(mesh, kappa),
            asm.permittivity_matrix(mesh, kappa, rows=rows_phi),
        ),
        ("A", asm.piezo_matrix(mesh, C, e, kappa), asm.piezo_matrix(mesh, C, e, kappa, rows=rows)),
    ]


def same_rows(whole: sp.csr_matrix, owned: sp.csr_matrix, rows: np.ndarray) -> bool:
    """owned holds whole's rows where `rows` holds, bit for bit and in whole's order, and
    nothing else."""
    if owned.shape != whole.shape:
        return False
    counts = np.diff(owned.indptr)  # (n,)
    if counts[~rows].any():
        return False
    for i in np.flatnonzero(rows):
        a, b = (
            slice(whole.indptr[i], whole.indptr[i + 1]),
            slice(owned.indptr[i], owned.indptr[i + 1]),
        )
        if not (
            np.array_equal(whole.indices[a], owned.indices[b])
            and np.array_equal(whole.data[a], owned.data[b])
        ):
            return False
    return True


@settings(max_examples=8, deadline=None)
@given(
    element=st.sampled_from(sorted(MESHES)),
    seed=st.integers(0, 2**32 - 1),
    mutate=st.sampled_from([None, "all dofs owned", "cells reversed"]),
)
# a short block whose rows sum at most two cells' terms: reversed, the same bits (a + b = b + a)
@example(element="quad", seed=13, mutate="cells reversed")
def test_owned_rows_are_the_whole_rows_bit_for_bit(element, seed, mutate):
    """A random contiguous block of rows (a rank's [lo, hi)) of each field. Mutations: the
    cells summed are those with every dof owned (a cell on the cut forgotten: rows on the
    partition's boundary short of a term), or the touching cells taken in reverse order (the
    same terms summed in another order: caught by the exact comparison on every row, where
    rows of three or more terms are; a random block may hold only rows of one or two terms,
    whose sum reversal leaves bit for bit: quad, seed 13, rows 77-78)."""
    mesh = MESHES[element]()
    rng = np.random.default_rng(seed)
    d, N = mesh.points.shape[1], mesh.n_nodes
    cut = np.sort(rng.choice(np.arange(1, (d + 1) * N), size=2, replace=False))
    rows = np.zeros((d + 1) * N, bool)
    rows[cut[0] : cut[1]] = True  # (d+1)N: a rank's rows of the coupled numbering
    if mutate == "cells reversed":
        rows[:] = True  # one rank: every row, its order of terms seen wherever it matters
    faults = {
        "all dofs owned": lambda r, keep: np.flatnonzero(keep[r].all(axis=1)),
        "cells reversed": lambda r, keep: np.flatnonzero(keep[r].any(axis=1))[::-1],
    }
    split = {"K": rows[: d * N], "G": rows[d * N :], "P": rows[d * N :], "A": rows}
    with pytest.MonkeyPatch.context() as mp:
        if mutate:
            mp.setattr(asm, "touching", faults[mutate])
        forms = _forms(mesh, rows[: d * N], rows[d * N :])
    found = {name: same_rows(W, O, split[name]) for name, W, O in forms}
    if mutate is None:
        assert all(found.values()), found
    else:
        assert not all(found.values()), (mutate, cut)


@pytest.mark.parametrize("element", sorted(MESHES))
def test_owned_rows_of_two_ranks_make_the_whole_matrix(element):
    """Two ranks' halves (the coupled numbering cut in the middle of the displacement rows)
    summed give the whole coupled operator exactly; each rank summed only its touching cells,
    fewer than all."""
    mesh = MESHES[element]()
    C, e, kappa = _materials(mesh.points.shape[1])
    n = (mesh.points.shape[1] + 1) * mesh.n_nodes
    first = np.arange(n) < n // 3
    whole = asm.piezo_matrix(mesh, C, e, kappa)
    halves = [asm.piezo_matrix(mesh, C, e, kappa, rows=r) for r in (first, ~first)]
    assert (abs(halves[0] + halves[1] - whole)).max() == 0.0
    u_rows = first[: mesh.points.shape[1] * mesh.n_nodes]
    dofs = asm.vector_dofs(mesh)
    assert asm.touching(dofs, u_rows).size < mesh.n_cells
