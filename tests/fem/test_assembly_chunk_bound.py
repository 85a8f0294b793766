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
