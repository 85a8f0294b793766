"""Jacobians of the cell maps and the refusal of inverted or degenerate cells, 2D and 3D."""

import numpy as np
import pytest

from fem.elements import reference_element
from fem.jacobians import _dets, check_cells, cofactors, determinants, jacobian_determinants
from fem.mesh import Mesh
from fem.meshing import box, rectangle, transform

from .mesh_checks import BOUNDS, wavy

SOLIDS = ["hexahedron", "tetra"]


@pytest.mark.parametrize("element", SOLIDS)
def test_inverted_cell_is_refused(element):
    mesh = box(*BOUNDS, (2, 2, 2), element)
    cells = mesh.cells.copy()
    swap = [1, 3] if element == "hexahedron" else [1, 2]
    cells[5, swap] = cells[5, swap[::-1]]  # mirror the local order: det J < 0
    with pytest.raises(ValueError, match="cell 5"):
        check_cells(Mesh(mesh.points, cells, mesh.boundaries))
    for chunk in (2, 3, 5):  # the cell in a later chunk keeps its global index
        with pytest.raises(ValueError, match=r"cell 5 \(.*1 bad cell"):
            check_cells(Mesh(mesh.points, cells, mesh.boundaries), chunk=chunk)
    with pytest.raises(ValueError, match="inverted"):
        transform(mesh, lambda p: p * np.array([1.0, 1.0, -1.0]))  # a reflection


def test_folded_hexahedron_is_refused():
    """Positive at all 8 corners but det J < 0 inside: the interior check is needed."""
    pts = np.array(
        [
            [0.5, 0.46, 0.42],
            [1.48, 0.1, -0.24],
            [-0.41, 0.43, 0.31],
            [1.12, 0.67, 0.47],
            [-0.6, 0.58, 0.51],
            [1.38, -0.58, 1.43],
            [0.37, 1.17, 0.6],
            [1.14, 0.76, 1.48],
        ]
    )  # a random perturbation of the unit cube, nodes in lexicographic order (found by search)
    folded = Mesh(pts, np.array([[0, 1, 3, 2, 4, 5, 7, 6]]))
    corners = np.array([[sx, sy, sz] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])
    assert jacobian_determinants(folded, corners).min() > 0
    with pytest.raises(ValueError, match="cell 0"):
        check_cells(folded)


def test_cofactors_and_determinants_against_numpy():
    J = np.random.default_rng(0).normal(size=(4, 5, 3, 3))
    cof = cofactors(J)
    det = np.linalg.det(J)
    assert np.allclose(cof, det[..., None, None] * np.linalg.inv(J).transpose(0, 1, 3, 2))
    mesh = transform(box(*BOUNDS, (1, 1, 1)), wavy)
    pts = np.random.default_rng(1).uniform(-1, 1, (6, 3))
    G = reference_element("hexahedron").gradients(pts)  # (6, 8, 3)
    Jm = np.einsum("cai,qaj->cqij", mesh.points[mesh.cells], G)
    assert np.allclose(jacobian_determinants(mesh, pts), np.linalg.det(Jm), rtol=1e-13)


def test_2d_cofactors_and_determinants_against_numpy():
    J = np.random.default_rng(2).normal(size=(4, 5, 2, 2))
    cof = cofactors(J)
    det = np.linalg.det(J)
    assert np.allclose(cof, det[..., None, None] * np.linalg.inv(J).transpose(0, 1, 3, 2))
    mesh = rectangle((0, 2), (0, 1), (2, 2), "quad")
    mesh = Mesh(mesh.points + 0.05 * np.sin(4 * mesh.points[:, ::-1]), mesh.cells)
    pts = np.random.default_rng(3).uniform(-1, 1, (6, 2))
    G = reference_element("quad").gradients(pts)  # (6, 4, 2)
    Jm = np.einsum("cai,qaj->cqij", mesh.points[mesh.cells], G)
    assert np.allclose(jacobian_determinants(mesh, pts), np.linalg.det(Jm), rtol=1e-13)


@pytest.mark.parametrize("element", ["quad", "triangle"])
def test_2d_clockwise_degenerate_and_nonconvex_cells_are_refused(element):
    mesh = rectangle((0, 2), (0, 1), (2, 2), element)
    check_cells(mesh)
    cells = mesh.cells.copy()
    cells[3] = cells[3, ::-1]  # clockwise
    with pytest.raises(ValueError, match="inverted or degenerate cell 3 "):
        check_cells(Mesh(mesh.points, cells))
    flat = mesh.points.copy()
    flat[:, 1] = 0.0  # every cell flattened onto the x axis
    with pytest.raises(ValueError, match="cell 0 "):
        check_cells(Mesh(flat, mesh.cells))
    if element == "quad":  # the centre node pushed past a diagonal: reflex corners
        centre = int(np.argmin(np.linalg.norm(mesh.points - [1.0, 0.5], axis=1)))
        bent = mesh.points.copy()
        bent[centre] = [1.9, 0.95]
        with pytest.raises(ValueError, match="inverted or degenerate"):
            check_cells(Mesh(bent, mesh.cells))


@pytest.mark.parametrize("d", [2, 3])
def test_cofactors_against_numpy(d):
    """cof = det(J) J⁻ᵀ; a transposed cofactor matrix (the adjugate) fails on a non-symmetric J."""
    J = np.random.default_rng(d).normal(size=(5, 4, d, d))
    expected = np.linalg.det(J)[..., None, None] * np.linalg.inv(J).transpose(0, 1, 3, 2)
    assert np.allclose(cofactors(J), expected, rtol=1e-12, atol=1e-12)
    assert not np.allclose(cofactors(J).transpose(0, 1, 3, 2), expected, rtol=1e-6)


def test_3d_determinants_from_row_0_are_the_cofactor_expansions_bit_for_bit():
    """`_dets` in 3D (row 0's cofactors only) equals `determinants(J, cofactors(J))` exactly on
    random stacks (mutation: a cofactor's sign flipped fails)."""
    J = np.random.default_rng(3).normal(size=(200, 7, 3, 3))  # (cells, points, 3, 3)
    assert np.array_equal(_dets(J), determinants(J, cofactors(J)))
    assert np.allclose(_dets(J), np.linalg.det(J))


@pytest.mark.parametrize("element", ["triangle", "quad"])
@pytest.mark.parametrize("size", [1e-4, 1e-7, 1e-9])
def test_a_small_well_shaped_cell_passes_a_flat_one_does_not(element, size):
    """Adaptive refinement toward a singular point makes cells 2^-k of the mesh's extent
    (`mixvi solve wavy_two_body --accuracy 0.02` reached ~1e-7 at cycle 18): a well-shaped cell
    of any size down to MIN_CELL passes; one flattened to 1e-15 of its own size does not.
    Against the mesh's extent^d (the rule before) the 1e-7 cell was refused."""
    mesh = rectangle((0, 1), (0, 1), (2, 2), element)
    corner = mesh.points.copy()
    near = mesh.points[:, 0] + mesh.points[:, 1] < 1e-12  # the node at the origin
    cells = mesh.cells[np.isin(mesh.cells, np.flatnonzero(near)).any(axis=1)]  # its cell(s)
    small = np.isin(np.arange(len(corner)), cells) & ~near
    corner[small] *= size / 0.5  # that cell shrunk to `size`, its shape kept
    check_cells(Mesh(corner, mesh.cells))
    flat = corner.copy()
    flat[small & (corner[:, 1] > 0), 1] = size * 1e-15
    with pytest.raises(ValueError, match="inverted or degenerate"):
        check_cells(Mesh(flat, mesh.cells))


def test_a_cell_below_min_cell_is_refused():
    """Below MIN_CELL × the extent the coordinates' rounding is a part of the cell's shape."""
    pts = np.array([[0.0, 0.0], [1e-11, 0.0], [0.0, 1e-11], [1.0, 1.0]])
    with pytest.raises(ValueError, match="degenerate cell 0"):
        check_cells(Mesh(pts, np.array([[0, 1, 2], [1, 3, 2]])))
