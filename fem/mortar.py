"""Dual mortar coupling of two non-matching boundary traces, in 2D and 3D (segment-based).

The multiplier space lives on the SLAVE trace, in the facet-local dual functions ψ_{e,a} of
`fem.facets` (a multiplier basis is Q·ψ, `fem.facets.multiplier_basis`). The master block is

    M[m e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π),

integrated over each slave facet e (m nodes per facet), where π maps a slave point x to the
master along the interpolated slave normal n = Σ_a φ_a n_a (Puso, Popp; nodal normals
n_k ∝ ∫_Γ φ_k n: averaged, continuous on curved boundaries). Where the slave facets meet the
master — the 2D segment overlaps and the 3D polygon clipping — is the only dimension-specific
part (`fem.clipping`): it hands back integration points in the reference coordinates of both
facets with weights on the slave facet, and `couple` integrates ψ_{e,a} φ_b^m on them for
every dimension.

Exactness: the row sums Σ_j M_kj = ∫ ψ_{e,a} over the covered part are polynomial integrals
where the slave facet is affine (a segment, a triangle or a parallelogram, on a curved
boundary or not): the rigid-body patch test holds to rounding. On straight/flat interfaces π is
affine and linear fields are transferred to rounding. The entries themselves have a rational
integrand (π along a varying normal), and on bilinear quadrilaterals that are not
parallelograms the inverse map is not polynomial either: `QUAD_ORDER` is chosen so that these
quadrature errors are ≤ 1e-13 relative on the test geometries.

Rigid-body patch test: for every multiplier row k, Σ_j D_kj = Σ_j M_kj when the support of ψ̃_k
is covered (Σ_j φ_j^m = 1); `patch_defect` measures max_k |Σ_j D_kj − Σ_j M_kj| / Σ_j D_kj,
`covered_nodes` tells the slave nodes whose whole support has the master behind it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from . import clipping
from .facets import Trace, facet_values, trace
from .mesh import Mesh

# Quadrature order of the 3D face integrals (mass, normals): exact on affine faces; on
# non-planar quadrilaterals (|N| not polynomial) biorthogonality holds to 5e-14 relative at 7 %
# warp. Segments are integrated in closed form.
FACE_ORDER = 12
# Default degree of the rule on every piece per facet type (the larger of slave and master is
# used): 5 Gauss points on a segment piece; on 3D cells the integrand is rational (the master
# point moves along the interpolated normal) and, on bilinear quadrilaterals that are not
# parallelograms, the inverse map is not polynomial either; at these orders M agrees with an
# order-24 rule to ≤ 1e-13 relative on the test geometries
# (tests/fem/test_mortar.py::test_cell_rule_default_is_converged). Triangles: order 6, the
# 16-point collapsed Gauss rule (`fem.elements`); Dunavant's 7-point order-5 rule leaves 3e-12.
QUAD_ORDER = {"line": 9, "triangle": 6, "quad": 10}


@dataclass(frozen=True, eq=False)
class Mortar:
    """The segment-based dual mortar coupling of a slave and a master trace.

    slave, master : the two traces (`fem.facets.Trace`); global ids in slave.nodes,
        master.nodes.
    M : (m·n_f, k_m) csr, M[m e + a, j] = ∫_e ψ_{e,a} (φ_j^m ∘ π) (module docstring).
    coverage : (n_f,) fraction of each slave facet mapped onto the master (0 … 1).
    n_cells : number of overlap cells (2D pieces, 3D non-empty clip polygons).
    """

    slave: Trace
    master: Trace
    M: sp.csr_matrix
    coverage: np.ndarray
    n_cells: int

    @property
    def slave_nodes(self) -> np.ndarray:
        """(k,) global slave node ids (`Trace.nodes` order)."""
        return self.slave.nodes

    @property
    def master_nodes(self) -> np.ndarray:
        """(k_m,) global master node ids (the columns of M)."""
        return self.master.nodes


def mortar_coupling(
    slave: Mesh,
    slave_part: str | Sequence[str],
    master: Mesh,
    master_part: str | Sequence[str],
    quad_order: int | None = None,
    reach: float = 1.0,
    face_order: int = FACE_ORDER,
) -> Mortar:
    """The dual mortar matrices of `slave_part` against `master_part` (`couple` on their
    traces).

    face_order : quadrature order of the 3D face integrals (`fem.facets.trace`): a caller
        whose slave block D = diag(∫φ_k) comes from a trace of another order passes that
        order, so that D and the dual basis in M agree on non-planar faces.
    """
    s = trace(slave, slave_part, face_order)
    return couple(s, trace(master, master_part, face_order), quad_order, reach)


def _local(wt: np.ndarray, psi: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(n, m_s, m_m) Σ_q wt ψ_a φ_b: the contributions of the pieces to M."""
    return np.einsum("tq,tqa,tqb->tab", wt, psi, phi)


def couple(s: Trace, m: Trace, quad_order: int | None = None, reach: float = 1.0) -> Mortar:
    """The dual mortar matrices of slave trace `s` against master trace `m`.

    quad_order : degree of the rule on every overlap piece (2D) or cell triangle (3D);
        default the larger `QUAD_ORDER` of the two facet types (3 is exact for affine faces;
        bilinear quadrilaterals that are not parallelograms need more).
    reach : how far apart candidate facets may be, in slave facet sizes
        (`fem.clipping.segment_pieces`, `fem.clipping.polygon_pieces`); the default admits
        interfaces that coincide up to about one slave facet size.
    Cost: O(n_pieces · q) with n_pieces ≈ (slave facets) × (master facets per slave facet).
    """
    if quad_order is None:
        quad_order = max(QUAD_ORDER[s.facet_type], QUAD_ORDER[m.facet_type])
    pieces = clipping.segment_pieces if s.points.shape[1] == 2 else clipping.polygon_pieces
    p = pieces(s, m, reach, quad_order)
    phi_s = facet_values(s.facet_type, p.xi_s)  # (n, q, m_s)
    psi = np.einsum("tqb,tab->tqa", phi_s, s.dual[p.e])  # (n, q, m_s)
    phi_m = facet_values(m.facet_type, p.xi_m)  # (n, q, m_m)
    loc = _local(p.weights, psi, phi_m)  # (n, m_s, m_m)
    ms = s.facets.shape[1]
    rows = np.broadcast_to((ms * p.e[:, None] + np.arange(ms))[:, :, None], loc.shape)
    cols = np.broadcast_to(m.facets[p.f][:, None, :], loc.shape)
    M = sp.csr_matrix((loc.ravel(), (rows.ravel(), cols.ravel())), shape=(s.facets.size, m.size))
    n_f = s.facets.shape[0]
    coverage = np.bincount(p.e, p.weights.sum(axis=1), minlength=n_f) / s.measures
    return Mortar(s, m, M, coverage, p.n_cells)


def patch_defect(Ds: sp.spmatrix, M: sp.spmatrix) -> np.ndarray:
    """Per multiplier row k: |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj (0 ⇔ rigid translations are
    transferred exactly by row k)."""
    d = np.asarray(Ds.sum(axis=1)).ravel()
    m = np.asarray(M.sum(axis=1)).ravel()
    return np.abs(d - m) / d


def nodal_rows(mo: Mortar) -> sp.csr_matrix:
    """(k, k_m) M in nodal rows, Σ_a over the facets around each slave node: the rows of
    Q·M for `multiplier_basis(…, ends="keep")` with every node carrying, whose slave block is
    D = diag(weights)."""
    s = mo.slave
    P = sp.csr_matrix(
        (np.ones(s.facets.size), (s.facets.ravel(), np.arange(s.facets.size))),
        shape=(s.size, s.facets.size),
    )
    return (P @ mo.M).tocsr()


# A slave facet counts as covered by the master if at most COVER_TOL of it is not: the rounding
# of the sum of its clipped pieces, nothing more. Measured deficit of fully covered facets:
# ≤ 5.6e-16 on every shipped two-body scene (2D and 3D, levels 0-2) and ≤ 8.9e-16 on the curved
# non-matching sphere and cylinder pairs of tests/fem/test_mortar.py (warped Q1 faces too), so
# 1e-12 keeps a factor 1000 over rounding; a looser bound (the 3D contact plug-in's former
# 1e-9) would keep rows whose support misses up to that share of master, whose rigid-body
# transfer (patch test) is then off by about as much, silently.
COVER_TOL = 1e-12


def covered_nodes(mo: Mortar, tol: float = COVER_TOL) -> np.ndarray:
    """(k,) bool: the master lies behind every facet around the slave node (coverage ≥ 1 − tol);
    only such nodes can carry a multiplier whose rigid-body row is exact."""
    bad = mo.coverage < 1.0 - tol  # (n_f,)
    out = np.ones(mo.slave.size, dtype=bool)
    out[mo.slave.facets[bad].ravel()] = False
    return out
