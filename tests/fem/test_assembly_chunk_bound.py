"""The chunk of cells assembled at a time is bounded by the entries of its local matrices per
quadrature point (`fem.assembly.LOCAL_ENTRIES`), not only by a cell count: hexahedra (8 points,
24 dofs) in CHUNK cells held the 3D build's peak memory (docs/benchmarks.md)."""

from __future__ import annotations

import pytest

import fem.assembly as asm
from fem.assembly import elasticity_matrix

from .helpers import same_matrix
from .test_assembly import PIEZO, _one_shot_elasticity, wavy_box


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_chunks_hold_at_most_local_entries_and_sum_the_same(monkeypatch, element):
    mesh = wavy_box(element, n=2)
    reference = _one_shot_elasticity(mesh, PIEZO.C)
    ref = asm.reference_element(mesh.cell_type)
    n_qp = ref.quadrature(ref.form_order)[1].size
    r = 3 * mesh.cells.shape[1]  # local dofs of a cell
    per_cell = n_qp * r * r
    monkeypatch.setattr(asm, "LOCAL_ENTRIES", 3 * per_cell)  # chunks of 3 cells
    sizes: list[int] = []
    geometry = asm._geometry

    def recording(mesh, pts, wts, cells=slice(None)):
        g = geometry(mesh, pts, wts, cells)
        sizes.append(g.w.shape[0])
        return g

    monkeypatch.setattr(asm, "_geometry", recording)
    assert same_matrix(elasticity_matrix(mesh, PIEZO.C), reference)
    assert max(sizes) == 3 and sum(sizes) == mesh.n_cells


@pytest.mark.parametrize("fault", [None, "first point dropped", "points reversed"])
def test_sum_points_is_the_sum_over_points_bit_for_bit(fault):
    """`fem.assembly._sum_points` (the kernels' Σ_q left_q @ right_q without the per-point
    array) gives `(left @ right).sum(axis=1)` exactly, so A is the same bit for bit as before
    it. Mutations: the first point dropped, the points summed in reverse order (the same sum
    in another order: caught by the exact comparison)."""
    import numpy as np

    rng = np.random.default_rng(7)
    left = rng.standard_normal((5, 8, 24, 6))  # (k, n_qp, r, s)
    right = rng.standard_normal((5, 8, 6, 24))  # (k, n_qp, s, c)
    if fault == "first point dropped":
        got = asm._sum_points(left[:, 1:], right[:, 1:])
    elif fault == "points reversed":
        got = asm._sum_points(left[:, ::-1], right[:, ::-1])
    else:
        got = asm._sum_points(left, right)
    assert np.array_equal(got, (left @ right).sum(axis=1)) == (fault is None)
