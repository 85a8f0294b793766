"""Tests of fem.mortar (with fem.clipping) and the multiplier bases of fem.facets, 2D and 3D.

2D (segments): biorthogonality, the rigid-body patch test on any interface (arcs up to 3 rad,
polylines, wavy curves, perturbed nodes, both orientations), linear reproduction, coverage, end
treatments, the tied patch test — and mutation tests showing that the checks catch a dropped
entry and a wrong projection.

3D (faces): the rigid-body and linear patch tests on flat and curved non-matching surfaces
(cylinder and sphere segments, triangles against quadrilaterals), the area, face-wise
biorthogonality of the dual basis, invariance under rotations, the boundary modification
(tied patch test with crosspoints), a brute-force computation of M by fine sampling — and
mutation tests showing that these checks catch a dropped cell, transposed local blocks, a
wrong normal and an unmodified basis at crosspoints."""

import dataclasses
import functools

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given, settings
from hypothesis import strategies as st

import fem.clipping as fc
import fem.mortar as fm
from fem.assembly import permittivity_matrix
from fem.elements import reference_element
from fem.facets import Trace, dual_mass, multiplier_basis, rim_nodes, trace
from fem.mapped import coons_block, reparametrise, segment
from fem.mesh import Mesh
from fem.meshing import box, extrude, transform
from fem.mortar import couple, mortar_coupling, patch_defect
from fem.shapes import cradle, half_disc

LINEAR = [lambda x: np.ones(len(x)), lambda x: x[:, 0], lambda x: x[:, 1]]
LINEAR += [lambda x: 0.3 - 1.7 * x[:, 0] + 2.9 * x[:, 1]]
ANGLES = np.round(np.arange(0.1, 3.0 + 1e-9, 0.1), 10)  # 0.1 … 3.0 rad


def random_knots(n, seed):
    steps = np.random.default_rng(seed).uniform(0.4, 1.6, n)  # (n,)
    return np.concatenate([[0.0], np.cumsum(steps) / steps.sum()])


def rectangle(y0, nx, ny, iface, seed):
    """[0, 1] × [y0, y0 + 1]; the side at y = 1 is the part "iface" with random node spacing."""
    c00, c10, c11, c01 = (0.0, y0), (1.0, y0), (1.0, y0 + 1), (0.0, y0 + 1)
    bottom, top = segment(c00, c10), segment(c11, c01)
    if iface == "top":
        top = reparametrise(top, random_knots(nx, seed))
    else:
        bottom = reparametrise(bottom, random_knots(nx, seed))
    names = {"bottom": "bottom", "right": "right", "top": "top", "left": "left"}
    names[iface] = "iface"
    return coons_block(bottom, segment(c10, c11), top, segment(c01, c00), nx, ny, names)


def stacked(n_lower=7, n_upper=5, seed=0):
    """Two non-matching rectangles meeting along y = 1: (lower, upper)."""
    return rectangle(0.0, n_lower, 3, "top", seed), rectangle(1.0, n_upper, 4, "bottom", seed + 1)


def polyline(vertices):
    """The polyline through `vertices`, parametrised by normalised arc length."""
    V = np.asarray(vertices, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(V, axis=0), axis=1))])
    s /= s[-1]

    def curve(t):
        t = np.asarray(t, dtype=float)
        return np.stack([np.interp(t, s, V[:, 0]), np.interp(t, s, V[:, 1])], axis=-1)

    return curve


def wave(t):
    """A smooth non-circular curve (varying curvature of both signs)."""
    t = np.asarray(t, dtype=float)
    return np.stack([t, 0.12 * np.sin(2 * np.pi * t) * (1 + 0.5 * t)], axis=-1)


CURVES = {
    "polyline": polyline([(0, 0), (0.3, 0.15), (0.55, -0.1), (1, 0.05)]),
    "wave": wave,
}


def curve_blocks(curve, n_lower, n_upper, seed):
    """Two blocks meeting along `curve` (part "iface" of each), random node spacing on it."""
    c0, c1 = curve(np.array([0.0, 1.0]))
    lo, hi = -0.6, 0.6
    top = reparametrise(lambda t: curve(1.0 - np.asarray(t)), random_knots(n_lower, seed))
    bottom = reparametrise(curve, random_knots(n_upper, seed + 1))
    lower = coons_block(
        segment((c0[0], lo), (c1[0], lo)), segment((c1[0], lo), c1), top,
        segment(c0, (c0[0], lo)), n_lower, 3, {"top": "iface"},
    )  # fmt: skip
    upper = coons_block(
        bottom, segment(c1, (c1[0], hi)), segment((c1[0], hi), (c0[0], hi)),
        segment((c0[0], hi), c0), n_upper, 3, {"bottom": "iface"},
    )  # fmt: skip
    return lower, upper


def blocks(mo, carry=None, ends="keep"):
    """(Ds, M) of the multiplier rows: Q·dual_mass and Q·M."""
    tr = mo.slave
    carry = np.ones(tr.size, dtype=bool) if carry is None else carry
    Q = multiplier_basis(tr, carry, ends)
    return Q @ dual_mass(tr), Q @ mo.M


def translation_error(mo, carry=None, ends="keep"):
    """max_k |(Ds c − M c)_k| / Σ_j Ds_kj for a unit translation c: the transfer error."""
    Ds, M = blocks(mo, carry, ends)
    ones_s, ones_m = np.ones(Ds.shape[1]), np.ones(M.shape[1])
    return float(np.max(np.abs(Ds @ ones_s - M @ ones_m) / (Ds @ ones_s)))


@functools.lru_cache(maxsize=256)
def paper_meshes(level, angle, n_disc, n_cradle):
    """(half disc, cradle) — cached: both orientations of a test use the same meshes."""
    d = half_disc(angle=angle, n_contact=n_disc, level=level)
    return d, cradle(angle=angle, n_contact=n_cradle, level=level)


def paper(level, angle=np.pi / 2, n_slave=8, n_master=12, swap=False):
    d, c = paper_meshes(level, float(angle), n_slave, n_master)
    s, m = (c, d) if swap else (d, c)
    return s, m, mortar_coupling(s, "contact", m, "contact")


# ---------------------------------------------------------------- the rigid-body patch test
@pytest.mark.parametrize("swap", [False, True], ids=["disc-slave", "cradle-slave"])
@pytest.mark.parametrize("sizes", [(8, 12), (8, 8), (12, 5)], ids=["8:12", "matching", "12:5"])
def test_rigid_translation_on_arcs_up_to_three_radians(sizes, swap):
    """Coverage 1 and patch defect ≤ 1e-12 for arc angles 0.1 … 3.0 (the old global root
    choice gave coverage 2 and defect 0.44 beyond ~π/2)."""
    for angle in ANGLES:
        for level in (0, 1):
            _, _, mo = paper(level, angle, *sizes, swap=swap)
            np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-13)
            assert translation_error(mo) <= 1e-12, (angle, level)
            assert patch_defect(*blocks(mo)).max() <= 1e-12, (angle, level)


@pytest.mark.parametrize("angle, level", [(0.3, 2), (1.6, 4), (2.8, 4), (3.0, 4)])
def test_rigid_translation_on_fine_arcs(angle, level):
    """Up to level 4 (128 : 192 segments): the defect stays at rounding level as h → 0 (small
    angles only to level 2: the half disc's element size follows the arc, so its mesh grows
    like 1/angle²)."""
    for swap in (False, True):
        _, _, mo = paper(level, angle, swap=swap)
        np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-13)
        assert patch_defect(*blocks(mo)).max() <= 1e-12


@pytest.mark.parametrize("swap", [False, True])
@pytest.mark.parametrize("name", sorted(CURVES))
@pytest.mark.parametrize("sizes", [(7, 5), (6, 6), (23, 31)])
def test_rigid_translation_on_non_circular_interfaces(name, sizes, swap):
    lower, upper = curve_blocks(CURVES[name], *sizes, seed=sum(sizes))
    s, m = (lower, upper) if swap else (upper, lower)
    mo = mortar_coupling(s, "iface", m, "iface")
    np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-13)
    assert translation_error(mo) <= 1e-12
    for carry_ends in (True, False):  # merged ends: the modified basis transfers it as well
        carry = np.ones(mo.slave.size, dtype=bool)
        carry[[0, -1]] = carry_ends
        assert translation_error(mo, carry, "merge") <= 1e-12


def _perturb(mesh: Mesh, part: str, rng, along: float, across: float) -> Mesh:
    """Move the interior nodes of `part` by up to along·h along it and across·h across it."""
    tr = trace(mesh, part)
    pts = mesh.points.copy()
    h = np.minimum(tr.measures[:-1], tr.measures[1:])  # (k − 2,) the shorter adjacent segment
    inner = tr.nodes[1:-1]
    shift = rng.uniform(-along, along, inner.size)[:, None] * tr.tangents[1:-1]
    shift += rng.uniform(-across, across, inner.size)[:, None] * tr.normals[1:-1]
    pts[inner] += h[:, None] * shift
    return Mesh(pts, mesh.cells, mesh.boundaries)


@settings(max_examples=60)
@given(seed=st.integers(0, 2**32 - 1))
def test_rigid_translation_with_perturbed_nodes(seed):
    """Random angle, sizes, orientation; interface nodes moved along and off the arc."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.1, 3.0)
    ns, nm = rng.integers(2, 25, size=2)
    d = _perturb(half_disc(angle=angle, n_contact=ns), "contact", rng, 0.3, 0.05)
    c = _perturb(cradle(angle=angle, n_contact=nm), "contact", rng, 0.3, 0.05)
    s, m = (d, c) if rng.random() < 0.5 else (c, d)
    mo = mortar_coupling(s, "contact", m, "contact")
    np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-13)
    assert translation_error(mo) <= 1e-12
    assert patch_defect(*blocks(mo)).max() <= 1e-12


def test_wide_arc_was_the_failure_of_a_global_root_choice():
    """The issue's case (arc angle 2.0): every slave segment is covered exactly once."""
    _, _, mo = paper(1, 2.0)
    assert mo.coverage.max() <= 1.0 + 1e-15 and mo.coverage.min() >= 1.0 - 1e-15


# ---------------------------------------------------------------- mutation tests
def test_mutation_dropped_entry_fails_the_patch_test():
    _, _, mo = paper(1, 2.0)
    M = mo.M.tolil()
    r, c = mo.M.nonzero()
    M[r[7], c[7]] = 0.0  # a dropped M entry
    broken = dataclasses.replace(mo, M=sp.csr_matrix(M))
    assert patch_defect(*blocks(broken)).max() > 1e-3
    assert translation_error(broken) > 1e-3


def folded_master(n_layer=4, gap=0.5):
    """A Z-folded master chain below the slave y = 1 of `stacked`: layers at y = 1 (facing the
    slave), 1 − gap (facing away) and 1 − 2·gap (facing it again). Only the trace is used."""
    xs = np.linspace(1.0, 0.0, n_layer + 1)
    layers = [
        np.column_stack([xs, np.full_like(xs, 1.0)]),
        np.column_stack([xs[::-1], np.full_like(xs, 1.0 - gap)]),
        np.column_stack([xs, np.full_like(xs, 1.0 - 2 * gap)]),
    ]
    pts = np.vstack(layers)  # (3(n+1), 2): each layer's end joined to the next's start
    edges = [(i, i + 1) for i in range(pts.shape[0] - 1)]
    return Mesh(pts, np.zeros((0, 4), dtype=int), {"iface": np.array(edges)})


def test_folded_master_keeps_the_nearest_hit():
    """The slave's normal lines meet two facing layers of a folded master; the nearer one
    is kept, so each slave segment is covered once."""
    _, upper = stacked()
    master = folded_master()
    for reach in (1.0, 10.0):
        mo = mortar_coupling(upper, "iface", master, "iface", reach=reach)
        np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-14)
        assert patch_defect(*blocks(mo)).max() <= 1e-12
        assert set(np.unique(mo.M.nonzero()[1])) <= set(range(5))  # only the top layer


def test_mutation_without_nearest_hit_selection_double_counts(monkeypatch):
    """Without keeping the nearest hit only, the far facing layer is counted too."""
    _, upper = stacked()
    monkeypatch.setattr(fc, "_nearest", lambda e, f, lo, hi, geometry: (e, f, lo, hi))
    broken = mortar_coupling(upper, "iface", folded_master(), "iface", reach=10.0)
    assert broken.coverage.max() > 1.5
    assert patch_defect(*blocks(broken)).max() > 1e-3


def _global_root_choice(xa, xb, na, nb, ya, yb):
    """TEST-ONLY: the projection this module replaced — each master node's parameter is the
    root nearest t = 1/2 of its quadratic, clipped to [0, 1]; a pair covers [min, max]."""
    d1, n1 = xb - xa, nb - na
    T = []
    for y in (ya, yb):
        d0 = xa - y
        a, b, c = fc._cross(d1, n1), fc._cross(d0, n1) + fc._cross(d1, na), fc._cross(d0, na)
        with np.errstate(all="ignore"):
            q = -0.5 * (b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(b * b - 4 * a * c))
            r = np.stack([q / a, c / q], axis=1)  # (n, 2)
        r = np.where(np.isfinite(r), r, np.inf)
        T.append(r[np.arange(len(r)), np.argmin(np.abs(r - 0.5), axis=1)])
    lo = np.clip(np.minimum(*T), 0.0, 1.0)
    hi = np.clip(np.maximum(*T), 0.0, 1.0)
    p = np.flatnonzero(hi - lo > 1e-14)
    return p, lo[p], hi[p]


def test_mutation_global_root_choice_fails_the_patch_test(monkeypatch):
    """The issue's fault, re-injected: on an arc of 2 rad the old root choice covers slave
    segments up to twice and the patch test fails (the issue measured a defect of 0.44)."""
    s, m, _ = paper(1, 2.0)
    monkeypatch.setattr(fc, "_overlaps", _global_root_choice)
    monkeypatch.setattr(fc, "_nearest", lambda e, f, lo, hi, geometry: (e, f, lo, hi))
    broken = mortar_coupling(s, "contact", m, "contact", reach=100.0)  # a global search
    assert broken.coverage.max() > 1.5
    assert patch_defect(*blocks(broken)).max() > 0.1


def test_mutation_uninterpolated_normal_breaks_the_mirror_symmetry(monkeypatch):
    """Projecting along a constant normal per slave segment (n(t) = n_a) still tiles the slave
    — the patch test cannot see it — but breaks the mirror symmetry of the paper geometry."""
    real = fc._pair_geometry

    def constant_normal(*args):
        xa, xb, na, nb, ya, yb = real(*args)
        return xa, xb, na, na, ya, yb

    monkeypatch.setattr(fc, "_pair_geometry", constant_normal)
    _, _, mo = paper(1)
    assert patch_defect(*blocks(mo)).max() <= 1e-12
    M = blocks(mo)[1].toarray()
    assert np.abs(M[::-1, ::-1] - M).max() > 1e-6 * M.max()


# ---------------------------------------------------------------- dual bases and ends
def dual_products(tr, ends, carry):
    """(n_carry, k) ∫ψ̃_k φ_j by 40-point Gauss on each slave segment, written out directly."""
    g, w = np.polynomial.legendre.leggauss(40)
    s, w = 0.5 * (g + 1), 0.5 * w
    phi = np.stack([1 - s, s])  # (2, n_qp)
    psi = np.stack([2 - 3 * s, 3 * s - 1])  # (2, n_qp): 2φ_1 − φ_2, 2φ_2 − φ_1
    rows = {node: k for k, node in enumerate(np.flatnonzero(carry))}
    out = np.zeros((len(rows), tr.size))
    for e, (a, b) in enumerate(tr.facets):
        for loc, node, other in ((0, a, b), (1, b, a)):
            target = node if carry[node] else (other if ends == "merge" and carry[other] else None)
            if target is not None:
                out[rows[target], [a, b]] += tr.measures[e] * (psi[loc] * w) @ phi.T
    return out


@pytest.mark.parametrize("ends", ["keep", "merge"])
@pytest.mark.parametrize("pattern", ["all", "ends", "one end", "interior"])
def test_multiplier_basis_is_biorthogonal(ends, pattern):
    s, _, _ = paper(1)
    tr = trace(s, "contact")
    carry = np.ones(tr.size, dtype=bool)
    drop = {"all": [], "ends": [0, -1], "one end": [-1], "interior": [3, 4]}[pattern]
    carry[drop] = False
    Ds = (multiplier_basis(tr, carry, ends) @ dual_mass(tr)).toarray()
    P = dual_products(tr, ends, carry)
    np.testing.assert_allclose(Ds, P, atol=1e-15)
    # biorthogonal among carrying nodes: the carrying columns are diag(∫φ_k)
    np.testing.assert_allclose(Ds[:, carry], np.diag(tr.weights[carry]), atol=1e-15)
    if ends == "merge":  # constants stay in the space: Σ_k ψ̃_k = 1 where a node carries
        some = carry[tr.facets].any(axis=1)  # (n_seg,) segments with a carrying node
        np.testing.assert_allclose(Ds.sum(), tr.measures[some].sum(), rtol=1e-14)
    else:  # keep: the dropped nodes' functions are gone, ∫Σψ̃ = Σ carrying weights
        np.testing.assert_allclose(Ds.sum(), tr.weights[carry].sum(), rtol=1e-14)


def test_merge_sends_the_end_function_to_the_neighbour():
    s, _, _ = paper(0)
    tr = trace(s, "contact")
    carry = np.ones(tr.size, dtype=bool)
    carry[[0, -1]] = False
    Q = multiplier_basis(tr, carry, "merge")
    Ds = (Q @ dual_mass(tr)).toarray()
    np.testing.assert_allclose(Ds[0, 0], 0.5 * tr.measures[0], rtol=1e-15)  # ∫_e0 1·φ_end
    np.testing.assert_allclose(Ds[0, 1], tr.weights[1], rtol=1e-15)
    assert Q.shape == (tr.size - 2, 2 * tr.facets.shape[0]) and Q.sum() == Q.shape[1]


def test_bad_basis_arguments():
    tr = trace(half_disc(), "contact")
    with pytest.raises(ValueError, match="ends"):
        multiplier_basis(tr, np.ones(tr.size, dtype=bool), "drop")
    with pytest.raises(ValueError, match="shape"):
        multiplier_basis(tr, np.ones(tr.size + 1, dtype=bool))


# ---------------------------------------------------------------- accuracy of the transfer
def test_linear_functions_converge_at_rate_two_on_the_arc():
    """D⁻¹M f(x_m) − f(x_s) = O(h²) on the arc: the two polylines are different chords.

    The error per unit |∇f| is compared with the sum of the two chord sagittas r(1 − cos(Δθ/2))
    (a natural scale for the distance between the polylines, not a proven bound).
    """
    errs, sagittas = [], []
    for level in range(4):
        d, c, mo = paper(level)
        xs, xm = d.points[mo.slave_nodes], c.points[mo.master_nodes]
        _, M = blocks(mo)
        D = mo.slave.weights
        grads = [1.0, 1.0, np.hypot(1.7, 2.9)]
        errs.append(
            max(
                np.abs(M @ f(xm) / D - f(xs)).max() / gr
                for f, gr in zip(LINEAR[1:], grads, strict=True)
            )
        )
        dth = np.pi / 2 / np.array([8, 12]) / 2**level
        sagittas.append(np.sum(1 - np.cos(dth / 2)))
    rate = -np.polyfit(np.arange(4), np.log2(errs), 1)[0]
    assert 1.9 < rate < 2.1, (errs, rate)
    assert (np.array(errs) < np.array(sagittas)).all(), (errs, sagittas)


def test_matching_curved_meshes_give_m_equal_to_d():
    """Identical node sets on the arc: π is the identity, so M = diag(D) exactly."""
    d, c = half_disc(level=1), cradle(n_contact=8, level=1)
    mo = mortar_coupling(d, "contact", c, "contact")
    xs, xm = d.points[mo.slave_nodes], c.points[mo.master_nodes]
    np.testing.assert_allclose(xs, xm[::-1], atol=1e-15)
    _, M = blocks(mo)
    np.testing.assert_allclose(M.toarray()[:, ::-1], np.diag(mo.slave.weights), atol=1e-13)


@pytest.mark.parametrize("level", [0, 2])
def test_coupling_respects_the_mirror_symmetry_of_the_paper_geometry(level):
    """The example is symmetric about x = 0; so is M (slave i ↔ ns−1−i, master j ↔ nm−1−j).

    This is sensitive to the projection direction: a normal that is not interpolated along
    the slave segment breaks the symmetry.
    """
    d, c, mo = paper(level)
    xs = d.points[mo.slave_nodes]
    np.testing.assert_allclose(xs[::-1] * [-1, 1], xs, atol=1e-14)
    M = blocks(mo)[1].toarray()
    np.testing.assert_allclose(M[::-1, ::-1], M, atol=1e-13 * M.max())


@pytest.mark.parametrize("slave_is_upper", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linear_functions_are_exact_on_a_straight_interface(slave_is_upper, seed):
    lower, upper = stacked(seed=seed)
    (s, m) = (upper, lower) if slave_is_upper else (lower, upper)
    mo = mortar_coupling(s, "iface", m, "iface")
    xs, xm = s.points[mo.slave_nodes], m.points[mo.master_nodes]
    assert np.ptp(np.diff(np.sort(xs[:, 0]))) > 0.05  # the spacing is really non-uniform
    np.testing.assert_allclose(mo.coverage, 1.0, atol=1e-14)
    carry = np.ones(mo.slave.size, dtype=bool)
    carry[[0, -1]] = False
    for f in LINEAR:
        Ds, M = blocks(mo)
        np.testing.assert_allclose(M @ f(xm), Ds @ f(xs), atol=1e-12, rtol=0)
        Ds, M = blocks(mo, carry, "merge")
        np.testing.assert_allclose(M @ f(xm), Ds @ f(xs), atol=1e-12, rtol=0)


def test_uncovered_slave_region_is_measured():
    """A master covering only x ∈ [0.3, 1] of the slave: the row sums miss exactly 0.3."""
    _, upper = stacked()
    c = [(0.3, 0.0), (1.0, 0.0), (1.0, 1.0), (0.3, 1.0)]
    short = coons_block(
        segment(c[0], c[1]), segment(c[1], c[2]), segment(c[2], c[3]), segment(c[3], c[0]), 4, 2,
        {"top": "iface"},
    )  # fmt: skip
    mo = mortar_coupling(upper, "iface", short, "iface")
    assert np.isclose(mo.M.sum(), 0.7, atol=1e-14)  # Σ_i ψ_i = 1: ∫ over the covered part
    ts = trace(upper, "iface")
    x0 = upper.points[ts.nodes[ts.facets]][:, :, 0]  # (n_seg, 2)
    expected = np.clip((x0.max(1) - 0.3) / (x0.max(1) - x0.min(1)), 0, 1)
    np.testing.assert_allclose(mo.coverage, expected, atol=1e-14)
    assert (mo.coverage < 1).any()


def test_back_facing_master_is_ignored():
    """The master's part with the same orientation as the slave's does not face it."""
    lower, upper = stacked()
    mo = mortar_coupling(upper, "iface", upper, "iface")
    assert mo.M.nnz == 0 and (mo.coverage == 0).all()


# ---------------------------------------------------------------- test-only Q1 Laplace assembly


def _q1_laplace(mesh):
    """TEST-ONLY: the Q1 stiffness ∫∇u·∇v with 2×2 Gauss, vectorised over cells."""
    g = np.array([-1.0, 1.0]) / np.sqrt(3.0)
    xi, eta = np.meshgrid(g, g, indexing="ij")
    xi, eta = xi.ravel(), eta.ravel()  # (4,) points, weights 1
    sx, sy = np.array([-1, 1, 1, -1]), np.array([-1, -1, 1, 1])
    dN = 0.25 * np.stack(
        [sx[None] * (1 + sy[None] * eta[:, None]), sy[None] * (1 + sx[None] * xi[:, None])], -1
    )  # (n_qp, 4, 2) reference gradients
    X = mesh.points[mesh.cells]  # (n_cells, 4, 2)
    J = np.einsum("cki,qkj->cqij", X, dN)  # (n_cells, n_qp, 2, 2), J_ij = ∂x_i/∂ξ_j
    det = np.linalg.det(J)  # (n_cells, n_qp)
    G = np.einsum("qkj,cqji->cqki", dN, np.linalg.inv(J))  # (n_cells, n_qp, 4, 2)
    Ke = np.einsum("cqai,cqbi,cq->cab", G, G, det)  # (n_cells, 4, 4)
    rows = np.repeat(mesh.cells, 4, axis=1)  # (n_cells, 16)
    cols = np.tile(mesh.cells, (1, 4))
    n = mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n))


def _select(nodes, n):
    """(len(nodes), n) the 0/1 matrix picking the trace nodes out of all mesh nodes."""
    k = nodes.size
    return sp.csr_matrix((np.ones(k), (np.arange(k), nodes)), shape=(k, n))


def _tied_solve(slave, master, ends, dirichlet_parts, u_exact):
    """Solve the mortar-tied Laplace problem, Dirichlet data u_exact on the given parts.

    Slave interface nodes on a Dirichlet part carry no multiplier (crosspoints). Returns
    (u, u_exact at the nodes, multipliers); slave dofs first, then master dofs.
    """
    mo = mortar_coupling(slave, "iface", master, "iface")
    ns_all = slave.n_nodes
    K = sp.block_diag([_q1_laplace(slave), _q1_laplace(master)]).tocsr()  # (N, N)
    X = np.vstack([slave.points, master.points])  # (N, 2)
    N = X.shape[0]
    fixed = np.unique(
        np.concatenate(
            [slave.boundary_nodes(p) for p in dirichlet_parts if p in slave.boundaries]
            + [ns_all + master.boundary_nodes(p) for p in dirichlet_parts if p in master.boundaries]
        )
    )  # corners belong to two parts
    carry = ~np.isin(mo.slave_nodes, fixed)
    Ds, M = blocks(mo, carry, ends)
    B = sp.hstack(
        [Ds @ _select(mo.slave_nodes, ns_all), -M @ _select(mo.master_nodes, N - ns_all)]
    ).tocsr()  # (n_carry, N): B u = Ds u_s − M u_m
    free = np.setdiff1d(np.arange(N), fixed)
    u = np.zeros(N)
    u[fixed] = u_exact(X[fixed])
    A = sp.bmat([[K[free][:, free], B[:, free].T], [B[:, free], None]]).tocsc()
    rhs = np.concatenate([-K[free][:, fixed] @ u[fixed], -B[:, fixed] @ u[fixed]])
    sol = spla.spsolve(A, rhs)
    u[free] = sol[: free.size]
    return u, u_exact(X), sol[free.size :]


@pytest.mark.parametrize("seed", [0, 3])
def test_tied_patch_test_merge_reproduces_any_linear_field(seed):
    """Dirichlet data on all outer sides: the interface ends are crosspoints; with Wohlmuth's
    modification the tied solution is the linear field and λ its flux, up to the ends."""
    lower, upper = stacked(seed=seed)
    f = LINEAR[3]
    u, exact, lam = _tied_solve(upper, lower, "merge", ["top", "bottom", "left", "right"], f)
    np.testing.assert_allclose(u, exact, atol=1e-10, rtol=0)
    np.testing.assert_allclose(lam, 2.9, rtol=1e-10)  # λ = −∂u/∂n_s, n_s = (0, −1)


@pytest.mark.parametrize("seed", [0, 3])
def test_tied_patch_test_keep_reproduces_a_vertical_linear_field(seed):
    """ends="keep", all interface nodes free: Dirichlet on top/bottom, natural on the sides."""
    lower, upper = stacked(seed=seed)
    f = lambda x: 0.3 + 2.9 * x[:, 1]  # noqa: E731  zero flux through the sides
    u, exact, lam = _tied_solve(upper, lower, "keep", ["top", "bottom"], f)
    np.testing.assert_allclose(u, exact, atol=1e-10, rtol=0)
    np.testing.assert_allclose(lam, 2.9, rtol=1e-10)


# ================================================================ 3D: faces
HEX, TET = "hexahedron", "tetra"
PAIRS = [(HEX, TET), (TET, HEX), (HEX, HEX), (TET, TET)]


def surface(mesh: Mesh, part: str) -> Trace:
    """The trace of `mesh` on `part` at the mortar's default face order."""
    return trace(mesh, part, fm.FACE_ORDER)


def rotation(seed: int) -> np.ndarray:
    """A random proper rotation (3, 3) drawn from default_rng(seed)."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def cylinder(r, theta, cells, element, R=None):
    """(r, θ, z) ∈ r × theta × [0, 1] mapped onto a cylinder segment about the z axis;
    part "right" is the outer surface r = r1, "left" the inner r = r0."""
    b = box(r, theta, (0.0, 1.0), cells, element)

    def f(p):
        x = np.stack([p[:, 0] * np.cos(p[:, 1]), p[:, 0] * np.sin(p[:, 1]), p[:, 2]], axis=1)
        return x if R is None else x @ R.T

    return transform(b, f)


def sphere(r, theta, phi, cells, element, R=None):
    """(r, θ polar, φ azimuth) mapped onto a spherical shell segment; parts as `cylinder`."""
    b = box(r, theta, phi, cells, element)

    def f(p):
        rr, t, q = p.T
        x = np.stack([rr * np.sin(t) * np.cos(q), rr * np.sin(t) * np.sin(q), rr * np.cos(t)], 1)
        return x if R is None else x @ R.T

    return transform(b, f)


def flat(z, cells, element, side, R=None, shear=0.0):
    """[0, 1]² × [z0, z1] with non-uniform spacing in x and y (and, with shear, trapezoidal
    faces); its face `side` at the interface z = 1."""
    b = box((0.0, 1.0), (0.0, 1.0), z, cells, element)

    def f(p):
        x, y = p[:, 0] + 0.15 * np.sin(np.pi * p[:, 0]), p[:, 1] - 0.1 * np.sin(np.pi * p[:, 1])
        x = x + shear * x * (y - 0.5)  # keeps planes z = const planar
        q = np.stack([x, y, p[:, 2]], axis=1)
        return q if R is None else q @ R.T

    return transform(b, f)


@functools.lru_cache(maxsize=64)
def pair(kind, es, em, seed=None, level=0):
    """(slave trace, master trace) of non-matching meshes of one interface; the master
    extends beyond the slave (every slave face is covered)."""
    R = None if seed is None else rotation(seed)
    n = 2**level
    if kind == "flat":
        s = flat((1.0, 2.0), (3 * n, 4 * n, 1), es, "bottom", R)
        m = flat((0.0, 1.0), (5 * n, 3 * n, 1), em, "top", R)
        return surface(s, "bottom"), surface(m, "top")
    if kind == "trapezoid":
        s = flat((1.0, 2.0), (3 * n, 4 * n, 1), es, "bottom", R, shear=0.4)
        m = flat((0.0, 1.0), (5 * n, 3 * n, 1), em, "top", R, shear=0.4)
        return surface(s, "bottom"), surface(m, "top")
    if kind == "cylinder":
        s = cylinder((0.5, 1.0), (0.0, 1.2), (1, 5 * n, 4 * n), es, R)
        m = cylinder((1.0, 1.5), (-0.1, 1.3), (1, 7 * n, 3 * n), em, R)
        return surface(s, "right"), surface(m, "left")
    s = sphere((0.5, 1.0), (0.5, 1.3), (0.2, 1.4), (1, 5 * n, 6 * n), es, R)
    m = sphere((1.0, 1.5), (0.4, 1.4), (0.1, 1.5), (1, 7 * n, 4 * n), em, R)
    return surface(s, "right"), surface(m, "left")


def rigid_defect(mo):
    return patch_defect(dual_mass(mo.slave), mo.M).max()


def transfer_error(mo, f):
    """max_k |(M f_m − D f_s)_k| / D_k over the local rows, for a field f(x)."""
    D = dual_mass(mo.slave)
    d = np.asarray(D.sum(axis=1)).ravel()
    return np.abs(mo.M @ f(mo.master.points) - D @ f(mo.slave.points)).max() / d.min()


# ---------------------------------------------------------------- patch tests
@pytest.mark.parametrize("kind", ["flat", "trapezoid", "cylinder", "sphere"])
@pytest.mark.parametrize("es,em", PAIRS)
def test_rigid_body_patch_test(kind, es, em):
    """Σ_j M_kj = D_kk on every local row, every slave face covered once."""
    s, m = pair(kind, es, em)
    mo = couple(s, m)
    np.testing.assert_allclose(mo.coverage, 1.0, rtol=0, atol=1e-13)
    assert rigid_defect(mo) <= 1e-12
    assert mo.n_cells > s.facets.shape[0]  # really non-matching: faces are cut


def test_trapezoids_need_the_higher_default_order():
    """On the trapezoids of the sphere mesh the inverse map is not polynomial: the rigid-body
    defect falls with the order of the cell rule and the default order meets 1e-12."""
    s, m = pair("sphere", HEX, HEX)
    d = [rigid_defect(couple(s, m, q)) for q in (3, 6, 8)]
    assert d[0] > 1e-7 and d[0] > 100 * d[1] > 1e4 * d[2], d
    assert rigid_defect(couple(s, m)) <= 1e-12


@pytest.mark.parametrize(
    "kind,es,em", [("cylinder", TET, TET), ("sphere", TET, TET), ("sphere", HEX, TET)]
)
def test_cell_rule_default_is_converged(kind, es, em):
    """M at the default order agrees with an order-24 rule to 1e-13 (relative to max |M|);
    order 3 does not (the integrand is not polynomial)."""
    s, m = pair(kind, es, em)
    ref = couple(s, m, 24).M
    err = [abs(couple(s, m, q).M - ref).max() / abs(ref).max() for q in (3, None)]
    assert err[0] > 1e-11 and err[1] <= 1e-13, err


@pytest.mark.parametrize("kind", ["flat", "trapezoid"])
@pytest.mark.parametrize("es,em", PAIRS)
def test_linear_fields_are_transferred_exactly_on_a_plane(kind, es, em):
    s, m = pair(kind, es, em, seed=7)
    mo = couple(s, m)
    for c in np.random.default_rng(3).normal(size=(3, 4)):
        assert transfer_error(mo, lambda x, c=c: c[0] + x @ c[1:]) <= 1e-12


@pytest.mark.parametrize("es,em", PAIRS)
def test_axial_fields_are_transferred_exactly_on_a_cylinder(es, em):
    """On the cylinder every face normal is perpendicular to the axis (the faces are chords
    spanned by an axial edge), so π moves points radially: a + b z is transferred exactly."""
    mo = couple(*pair("cylinder", es, em))
    assert transfer_error(mo, lambda x: 0.3 - 1.7 * x[:, 2]) <= 1e-12
    assert transfer_error(mo, lambda x: x[:, 0]) > 1e-6  # x is not: the chords differ


def nodal_transfer_error(mo, f):
    """The weighted RMS over slave nodes of D⁻¹M f_m − f_s (local rows summed per node)."""
    s = mo.slave
    P = sp.csr_matrix((np.ones(s.facets.size), (s.facets.ravel(), np.arange(s.facets.size))))
    r = P @ (mo.M @ f(mo.master.points)) / s.weights - f(s.points)  # (k,)
    return np.sqrt((s.weights * r**2).sum() / s.weights.sum())


@pytest.mark.parametrize("kind", ["cylinder", "sphere"])
def test_linear_fields_converge_at_rate_two_on_curved_surfaces(kind):
    """D⁻¹M f_m − f_s = O(h²) for a linear f: the two discrete surfaces are different chords
    (measured rates 1.84, 1.96 on the cylinder and 2.17, 1.87 on the sphere, levels 0–2)."""
    f = lambda x: x @ np.array([0.6, -0.8, 0.5])  # noqa: E731
    errs = [nodal_transfer_error(couple(*pair(kind, HEX, TET, level=lv)), f) for lv in range(3)]
    rate = -np.polyfit(np.arange(3), np.log2(errs), 1)[0]
    assert 1.8 < rate < 2.2, (errs, rate)


@pytest.mark.parametrize("level,layers", [(0, 1), (1, 2)])
def test_extruded_2d_meshes_reproduce_the_2d_mortar(level, layers):
    """The paper's non-matching meshes (8 : 12 segments on the arc) extruded: summed over the
    layers' nodes, the 3D M is the 2D M (fem.mortar, interpolated normals) × thickness, to
    rounding; the cells, the projection and the dual basis reduce to 2D's in each section."""
    d, c = half_disc(level=level), cradle(level=level)
    mo2 = mortar_coupling(d, "contact", c, "contact")
    tr = mo2.slave
    P2 = sp.csr_matrix((np.ones(tr.facets.size), (tr.facets.ravel(), np.arange(tr.facets.size))))
    M2 = (P2 @ mo2.M).toarray()  # (ns, nm) nodal rows
    mo3 = mortar_coupling(
        extrude(d, (0.0, 0.3), layers), "contact", extrude(c, (0.0, 0.3), layers), "contact"
    )
    s3 = mo3.slave
    P3 = sp.csr_matrix((np.ones(s3.facets.size), (s3.facets.ravel(), np.arange(s3.facets.size))))
    M3 = (P3 @ mo3.M).tocoo()  # (ns3, nm3) nodal rows
    row = {g: i for i, g in enumerate(tr.nodes)}
    col = {g: j for j, g in enumerate(mo2.master_nodes)}
    M3to2 = np.zeros_like(M2)
    nd, nc = d.n_nodes, c.n_nodes
    for i, j, v in zip(M3.row, M3.col, M3.data, strict=True):  # node i + l·n → 2D node i
        M3to2[row[s3.nodes[i] % nd], col[mo3.master.nodes[j] % nc]] += v
    np.testing.assert_allclose(M3to2 / 0.3, M2, rtol=0, atol=1e-13 * np.abs(M2).max())
    assert rigid_defect(mo3) <= 1e-12


def test_mutation_projection_along_the_plane_normal_misses_the_2d_mortar(monkeypatch):
    """Projecting along each face's constant auxiliary normal n0 instead of the interpolated
    normal field (the textbook auxiliary-plane variant) still passes the rigid-body patch test
    but no longer reduces to the 2D mortar on an extruded mesh (5e-4 relative at level 0)."""
    monkeypatch.setattr(fc, "_rays", lambda face_type, X, y, xi, **kw: xi)
    with pytest.raises(AssertionError, match="Not equal"):
        test_extruded_2d_meshes_reproduce_the_2d_mortar(0, 1)


def test_nodal_rows_and_coverage_on_a_partly_covered_slave():
    """A master covering part of the slave: covered nodes have exact nodal rows (Σ_j M_kj =
    W_k), the others are flagged; with full coverage every node is covered."""
    s, m = pair("cylinder", HEX, TET)
    mo = couple(s, m)
    np.testing.assert_allclose(np.asarray(fm.nodal_rows(mo).sum(axis=1)).ravel(), s.weights)
    assert fm.covered_nodes(mo).all()
    short = cylinder((1.0, 1.5), (0.4, 1.3), (1, 4, 3), TET)  # θ from 0.4: the slave starts at 0
    mo = couple(s, surface(short, "left"))
    cov = fm.covered_nodes(mo)
    theta = np.arctan2(s.points[:, 1], s.points[:, 0])
    assert (~cov).any() and cov.any()
    assert (theta[~cov] < 0.4 + 0.25).all()  # only nodes next to the uncovered strip
    rows = np.asarray(fm.nodal_rows(mo).sum(axis=1)).ravel()
    np.testing.assert_allclose(rows[cov], s.weights[cov], rtol=1e-12)
    assert (np.abs(rows[~cov] - s.weights[~cov]) / s.weights[~cov]).max() > 0.1  # flagged rows


# ---------------------------------------------------------------- area and dual basis
def polyhedral_area(f):
    """The area of a trace from its node coordinates alone (planar faces split in triangles)."""
    X = f.points[f.facets]  # (n_f, m, 3)
    tri = [(0, 1, 2)] if f.facet_type == "triangle" else [(0, 1, 2), (0, 2, 3)]
    return sum(
        0.5 * np.linalg.norm(np.cross(X[:, b] - X[:, a], X[:, c] - X[:, a]), axis=1).sum()
        for a, b, c in tri
    )


@pytest.mark.parametrize("kind", ["cylinder", "sphere"])
@pytest.mark.parametrize("es,em", PAIRS)
def test_area_of_the_contact_surface_is_reproduced(kind, es, em):
    """Σ D_kk = Σ M_kj = the area of the slave surface (faces planar here)."""
    s, m = pair(kind, es, em)
    mo = couple(s, m)
    area = polyhedral_area(s)
    np.testing.assert_allclose(s.weights.sum(), area, rtol=1e-14)
    np.testing.assert_allclose(mo.M.sum(), area, rtol=1e-13)
    if kind == "cylinder":  # chord rectangles: n_θ · 2 sin(Δθ/2) · height
        np.testing.assert_allclose(area, 5 * 2 * np.sin(1.2 / 10), rtol=1e-14)


def fine_rule(face_type, n=12):
    """TEST-ONLY: reference points (p, 2) and weights by n × n sub-cells with 3×3 Gauss each
    (sub-triangles of a triangle), independent of the module's rules."""
    g, w = np.polynomial.legendre.leggauss(3)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    u = (np.arange(n)[:, None] + g[None, :]).ravel() / n  # (3n,)
    wu = np.tile(w, n) / n
    U, V = np.meshgrid(u, u, indexing="ij")
    W = np.outer(wu, wu)
    if face_type == "quad":
        return np.stack([2 * U.ravel() - 1, 2 * V.ravel() - 1], 1), 4 * W.ravel()
    # Duffy: (u, v) ∈ [0, 1]² ↦ (u, v(1 − u)), Jacobian 1 − u
    return np.stack([U.ravel(), (V * (1 - U)).ravel()], 1), (W * (1 - U)).ravel()


def warped(f: Trace, seed: int) -> Trace:
    """TEST-ONLY: the trace with nodes moved randomly off the surface by about 7 % of a face
    size (non-planar quadrilaterals)."""
    pts = np.zeros((f.nodes.max() + 1, 3))
    pts[f.nodes] = f.points + 0.01 * np.random.default_rng(seed).normal(size=f.points.shape)
    cells = np.zeros((0, 8 if f.facet_type == "quad" else 4), dtype=int)
    return surface(Mesh(pts, cells, {"p": f.nodes[f.facets]}), "p")


@pytest.mark.parametrize("kind", ["sphere", "warped"])
@pytest.mark.parametrize("element", [HEX, TET])
def test_dual_basis_is_biorthogonal_face_by_face(kind, element):
    """∫_e ψ_{e,a} φ_{e,b} dA = δ_ab ∫_e φ_a dA by an independent fine quadrature, on trapezoids
    (sphere) and on non-planar quadrilaterals (warped)."""
    s, _ = pair("sphere", element, TET)
    s = warped(s, 1) if kind == "warped" else s
    ref = reference_element(s.facet_type)
    pts, w = fine_rule(s.facet_type, 24)
    phi = ref.values(pts)  # (p, m)
    T = np.einsum("fai,paj->fpij", s.points[s.facets], ref.gradients(pts))  # (n_f, p, 3, 2)
    dA = np.linalg.norm(np.cross(T[..., 0], T[..., 1]), axis=-1) * w  # (n_f, p)
    psi = np.einsum("pb,fab->fpa", phi, s.dual)  # (n_f, p, m)
    G = np.einsum("fp,fpa,pb->fab", dA, psi, phi)  # (n_f, m, m)
    expect = s.facet_weights[:, :, None] * np.eye(phi.shape[1])[None]
    scale = s.facet_weights.max()
    np.testing.assert_allclose(G, expect, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(psi.sum(axis=2), 1.0, atol=1e-13)  # Σ_a ψ_a = 1


def test_dual_basis_of_affine_faces_is_the_classical_one():
    """P1 triangles: ψ_a = 3φ_a − Σ_{b≠a} φ_b; Q1 rectangles: tensor product of (2, −1)."""
    s, _ = pair("cylinder", TET, TET)
    A = 4 * np.eye(3) - 1
    np.testing.assert_allclose(s.dual, np.broadcast_to(A, s.dual.shape), atol=1e-13)
    s, _ = pair("cylinder", HEX, TET)
    one = np.array([[2.0, -1.0], [-1.0, 2.0]])
    A = np.kron(one, one)[np.ix_([0, 1, 3, 2], [0, 1, 3, 2])]  # (ξ, η) corner order of a quad
    np.testing.assert_allclose(s.dual, np.broadcast_to(A, s.dual.shape), atol=1e-13)


# ---------------------------------------------------------------- invariance
@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1))
def test_coupling_is_invariant_under_rotations(seed):
    """The same interface in a random orientation gives the same D and M (no axis is special:
    the in-plane axes of the auxiliary planes change, the matrices must not)."""
    kind = ["cylinder", "sphere", "trapezoid"][seed % 3]
    es, em = PAIRS[(seed // 3) % 4]
    base = couple(*pair(kind, es, em))
    rot = couple(*pair(kind, es, em, seed=seed))
    np.testing.assert_allclose(rot.slave.weights, base.slave.weights, rtol=1e-13)
    diff = abs(rot.M - base.M).max()
    assert diff <= 1e-13 * abs(base.M).max(), diff
    assert rigid_defect(rot) <= 1e-12


# ---------------------------------------------------------------- brute force
def brute_force_M(s, m, n_sub, faces):
    """TEST-ONLY: M by sampling each slave face on a fine sub-grid and shooting each sample x
    along its interpolated normal n(ξ) = Σ φ_a(ξ) n_a at every master face near it (no
    clipping, no auxiliary plane; the hit by Newton on the 3×3 system x_m(η) − α n = x; the
    nearest hit inside a master face is kept)."""
    ref_s, ref_m = reference_element(s.facet_type), reference_element(m.facet_type)
    pts, w = fine_rule(s.facet_type, n_sub)
    phi_s = ref_s.values(pts)  # (p, m_s)
    out = np.zeros((s.facets.size, m.size))
    cm = m.points[m.facets].mean(axis=1)  # (n_fm, 3)
    for e in faces:
        X = s.points[s.facets[e]]  # (m_s, 3)
        c = X.mean(axis=0)
        near = np.linalg.norm(cm - c, axis=1) < 3 * np.linalg.norm(X - c, axis=1).max()
        Xm, mf = m.points[m.facets[near]], m.facets[near]  # (n_near, m_m, 3): a generous prefilter
        T = np.einsum("ai,paj->pij", X, ref_s.gradients(pts))  # (p, 3, 2)
        dA = np.linalg.norm(np.cross(T[..., 0], T[..., 1]), axis=-1) * w  # (p,)
        xs = phi_s @ X  # (p, 3)
        ns = phi_s @ s.normals[s.facets[e]]  # (p, 3) the interpolated normal
        psi = phi_s @ s.dual[e].T  # (p, m_s)
        eta = np.zeros((len(xs), Xm.shape[0], 2)) + ref_m.centroid  # (p, n_near, 2)
        alpha = np.zeros((len(xs), Xm.shape[0]))
        for _ in range(8):  # Newton on x_m(η) − α n − x_s = 0 for every sample and face
            phi = ref_m.values(eta.reshape(-1, 2)).reshape(*eta.shape[:2], -1)
            dphi = ref_m.gradients(eta.reshape(-1, 2)).reshape(*eta.shape[:2], -1, 2)
            r = np.einsum("pfa,fai->pfi", phi, Xm) - alpha[..., None] * ns[:, None] - xs[:, None]
            dn = -np.broadcast_to(ns[:, None], r.shape)[..., None]  # (p, n_near, 3, 1) ∂/∂α
            J = np.concatenate([np.einsum("pfaj,fai->pfij", dphi, Xm), dn], axis=3)  # (.., 3, 3)
            step = np.linalg.solve(J, r[..., None])[..., 0]
            eta -= step[..., :2]
            alpha -= step[..., 2]
        lo, hi = (0.0, 1.0) if m.facet_type == "triangle" else (-1.0, 1.0)
        inside = (eta >= lo - 1e-12).all(axis=2) & (eta <= hi + 1e-12).all(axis=2)
        if m.facet_type == "triangle":
            inside &= eta.sum(axis=2) <= 1 + 1e-12
        dist = np.where(inside, np.abs(alpha), np.inf)  # (p, n_near)
        f = np.argmin(dist, axis=1)  # (p,) the nearest master face hit
        hit = np.isfinite(dist[np.arange(len(f)), f])
        phi_m = ref_m.values(eta[np.arange(len(f)), f])  # (p, m_m)
        loc = np.einsum("p,pa,pb->pab", dA * hit, psi, phi_m)  # (p, m_s, m_m)
        for a in range(s.facets.shape[1]):
            np.add.at(out[s.facets.shape[1] * e + a], mf[f].ravel(), loc[:, a].ravel())
    return out


@pytest.mark.parametrize("kind,es,em", [("sphere", HEX, TET), ("cylinder", TET, HEX)])
def test_m_agrees_with_a_brute_force_computation(kind, es, em):
    """The brute force converges to M at its own rate (the integrand has kinks along the
    master edges, so sampling converges like n_sub⁻²): halving its sub-cells divides the
    difference by about 4 (measured, max entry difference / max entry, n_sub = 8, 16:
    sphere 3.4e-4, 8.7e-5; cylinder 4.7e-4, 9.4e-5)."""
    s, m = pair(kind, es, em)
    faces = np.arange(0, s.facets.shape[0], 5)  # a sample of the slave faces, rim and inside
    rows = (s.facets.shape[1] * faces[:, None] + np.arange(s.facets.shape[1])).ravel()
    M = couple(s, m).M.toarray()[rows]
    d = [np.abs(brute_force_M(s, m, n, faces)[rows] - M).max() / np.abs(M).max() for n in (8, 16)]
    assert d[1] < 2e-4 and 3.0 < d[0] / d[1] < 8.0, d


# ---------------------------------------------------------------- boundary modification
def tied_solve(ends, seed):
    """Two non-matching boxes tied by the mortar, a scalar Laplace problem (κ = I), Dirichlet
    data u = linear on all outer sides: slave rim nodes lie on Dirichlet sides (crosspoints)
    and carry no multiplier. Returns (u, exact u, λ)."""
    R = rotation(seed)
    up = flat((1.0, 1.7), (3, 4, 2), HEX, "bottom", R)
    lo = flat((0.3, 1.0), (5, 3, 2), TET, "top", R)
    c = np.array([0.3, -1.2, 0.8, 2.1])
    u_ex = lambda x: c[0] + x @ c[1:]  # noqa: E731
    s, m = surface(up, "bottom"), surface(lo, "top")
    mo = couple(s, m)
    ns = up.n_nodes
    K = sp.block_diag([permittivity_matrix(up, np.eye(3)), permittivity_matrix(lo, np.eye(3))])
    X = np.vstack([up.points, lo.points])
    sides = [k for k in up.boundaries if k != "bottom"]
    fixed = np.unique(
        np.concatenate(
            [up.boundaries[k].ravel() for k in sides]
            + [ns + lo.boundaries[k].ravel() for k in lo.boundaries if k != "top"]
        )
    )
    carry = ~np.isin(s.nodes, fixed)
    assert (~carry).sum() == rim_nodes(s.facets).size  # the rim is on Dirichlet sides
    Q = multiplier_basis(s, carry, ends)
    Ds, Mq = Q @ dual_mass(s), Q @ mo.M
    pick = lambda nodes, n: sp.csr_matrix(  # noqa: E731
        (np.ones(nodes.size), (np.arange(nodes.size), nodes)), shape=(nodes.size, n)
    )
    B = sp.hstack([Ds @ pick(s.nodes, ns), -Mq @ pick(m.nodes, lo.n_nodes)]).tocsr()
    N = X.shape[0]
    free = np.setdiff1d(np.arange(N), fixed)
    u = np.zeros(N)
    u[fixed] = u_ex(X[fixed])
    K = K.tocsr()
    A = sp.bmat([[K[free][:, free], B[:, free].T], [B[:, free], None]]).tocsc()
    rhs = np.concatenate([-K[free][:, fixed] @ u[fixed], -B[:, fixed] @ u[fixed]])
    sol = spla.spsolve(A, rhs)
    u[free] = sol[: free.size]
    n_s = R @ np.array([0.0, 0.0, -1.0])  # the slave's outward normal
    return u, u_ex(X), sol[free.size :], -c[1:] @ n_s


@pytest.mark.parametrize("seed", [0, 5])
def test_tied_patch_test_with_crosspoints_reproduces_a_linear_field(seed):
    """With the boundary-modified dual basis the tied solution is the linear field and λ its
    constant flux, up to the rim."""
    u, exact, lam, flux = tied_solve("merge", seed)
    np.testing.assert_allclose(u, exact, atol=1e-10, rtol=0)
    np.testing.assert_allclose(lam, flux, rtol=1e-10)


def test_mutation_keep_at_crosspoints_fails_the_tied_patch_test():
    """Dropping the crosspoint functions without the modification loses constants near the
    rim: the tied solution is no longer the linear field."""
    u, exact, _, _ = tied_solve("keep", 0)
    assert np.abs(u - exact).max() > 1e-4


@pytest.mark.parametrize("kind,es,em", [("sphere", HEX, TET), ("cylinder", TET, HEX)])
def test_merge_ties_a_constant_multiplier_on_curved_non_matching_surfaces(kind, es, em):
    """The tied patch test of the multiplier on curved non-matching surfaces whose rim carries
    no multiplier (crosspoints): λ_h ≡ 1 in the modified basis (every coefficient 1) loads the
    master with Σ_k (Q M)_kj, which must be the load of the constant itself over the faces
    with a carrying node (Σ_a ψ_{e,a} = 1 on each face; a corner triangle of rim nodes only has
    no multiplier at all), ≤ 1e-12; the rigid-body rows of the covered nodes stay exact too.
    "keep" loses the rim faces' share of the constant (its mutation test)."""
    s, m = pair(kind, es, em)
    carry = np.ones(s.size, dtype=bool)
    carry[rim_nodes(s.facets)] = False
    some = np.repeat(carry[s.facets].any(axis=1), s.facets.shape[1])  # (m·n_f,) local rows
    assert some.mean() > 0.9
    mo = couple(s, m)
    exact = some @ mo.M  # (k_m,) ∫ φ_j^m ∘ π dA over the faces with a carrying node
    covered = fm.covered_nodes(mo)[carry]
    defects = {}
    for ends in ("merge", "keep"):
        Q = multiplier_basis(s, carry, ends)
        load = np.asarray((Q @ mo.M).sum(axis=0)).ravel()
        defects[ends] = np.abs(load - exact).max() / np.abs(exact).max()
        rigid = patch_defect(Q @ dual_mass(s), Q @ mo.M)[covered]
        assert rigid.max() <= 1e-12, (ends, rigid.max())
    assert defects["merge"] <= 1e-12 and defects["keep"] > 1e-2, defects


@pytest.mark.parametrize("element", [HEX, TET])
def test_boundary_modified_basis_keeps_biorthogonality_and_constants(element):
    s, _ = pair("sphere", element, TET)
    carry = np.ones(s.size, dtype=bool)
    carry[rim_nodes(s.facets)] = False
    Dl = dual_mass(s)
    for ends in ("merge", "keep"):
        Ds = (multiplier_basis(s, carry, ends) @ Dl).toarray()  # (n_carry, k)
        np.testing.assert_allclose(Ds[:, carry], np.diag(s.weights[carry]), rtol=1e-14)
    Q = multiplier_basis(s, carry, "merge")
    some = carry[s.facets].any(axis=1)  # (n_f,) faces with a carrying node
    m = s.facets.shape[1]
    cols = (m * np.flatnonzero(some)[:, None] + np.arange(m)).ravel()
    np.testing.assert_allclose(np.asarray(Q.sum(axis=0)).ravel()[cols], 1.0, rtol=1e-15)


def test_bad_basis_arguments_on_faces():
    s, _ = pair("flat", TET, TET)
    with pytest.raises(ValueError, match="ends"):
        multiplier_basis(s, np.ones(s.size, dtype=bool), "drop")
    with pytest.raises(ValueError, match="shape"):
        multiplier_basis(s, np.ones(s.size + 1, dtype=bool))


# ---------------------------------------------------------------- mutations
@pytest.mark.parametrize("kind", ["flat", "sphere"])
def test_mutation_dropped_cell_fails_the_patch_test(kind, monkeypatch):
    real = fc.cells

    def drop_one(*args, **kw):
        e, f, poly, count, *rest = real(*args, **kw)
        return (e[1:], f[1:], poly[1:], count[1:], *rest)

    monkeypatch.setattr(fc, "cells", drop_one)
    mo = couple(*pair(kind, HEX, TET))
    assert rigid_defect(mo) > 1e-3


@pytest.mark.parametrize("es", [HEX, TET])
def test_mutation_transposed_local_blocks_fail_the_patch_tests(es, monkeypatch):
    """∫φ_a ψ_b in place of ∫ψ_a φ_b (slave and master roles swapped in the local block)."""
    monkeypatch.setattr(
        fm, "_local", lambda wt, psi, phi: np.einsum("tq,tqa,tqb->tba", wt, psi, phi)
    )
    mo = couple(*pair("trapezoid", es, es, seed=2))
    assert rigid_defect(mo) > 1e-3
    assert transfer_error(mo, lambda x: x[:, 0] - 2 * x[:, 1]) > 1e-3


def test_mutation_wrong_normal_fails_the_patch_test(monkeypatch):
    """Nodal normals pointing into the body: no master face faces the slave."""
    real = fc._planes
    monkeypatch.setattr(fc, "_planes", lambda s: (lambda x0, n0, E: (x0, -n0, E))(*real(s)))
    mo = couple(*pair("cylinder", HEX, TET))
    assert rigid_defect(mo) > 0.5


def test_mutation_primal_basis_fails_the_linear_transfer(monkeypatch):
    """φ in place of ψ (A = I): row sums still agree on covered faces, linear fields do not."""
    s, m = pair("flat", TET, HEX, seed=4)
    broken = Trace(
        s.nodes, s.facets, s.facet_type, s.points, s.normals, s.weights, s.facet_weights,
        s.measures, np.broadcast_to(np.eye(3), s.dual.shape),
    )  # fmt: skip
    mo = couple(broken, m)
    assert transfer_error(mo, lambda x: x[:, 0]) > 1e-3


def _sheets(element: str, R=None, n: int = 2) -> Mesh:
    """n master boxes one above the other under the slave, their tops in one part "top": a
    master surface that the slave's normal lines meet n times (z = 1, 0.8, 0.6)."""
    boxes = [((0.0, 1.0), (5, 3, 1)), ((0.3, 0.8), (4, 6, 1)), ((0.1, 0.6), (3, 3, 1))][:n]
    meshes = [flat(z, cells, element, "top", R) for z, cells in boxes]
    off = np.cumsum([0] + [b.points.shape[0] for b in meshes])
    return Mesh(
        np.vstack([b.points for b in meshes]),
        np.vstack([b.cells + o for b, o in zip(meshes, off, strict=False)]),
        {"top": np.vstack([b.boundaries["top"] + o for b, o in zip(meshes, off, strict=False)])},
    )


@pytest.mark.parametrize("es,em", [(HEX, TET), (TET, HEX)])
def test_a_folded_master_couples_with_its_nearest_sheet_only(es, em):
    """Nearest hit: with a second master sheet 0.2 below the first, M is the coupling with the
    upper sheet alone (≤ 1e-13 × max) and the lower sheet's columns are zero; the coverage stays
    1. Mutation: without the taken-back overlaps (nearest_hits a no-op) both sheets count."""
    R = rotation(3)
    s = surface(flat((1.0, 2.0), (3, 4, 1), es, "bottom", R), "bottom")
    both = surface(_sheets(em, R), "top")
    upper = surface(flat((0.0, 1.0), (5, 3, 1), em, "top", R), "top")
    mo, ref = couple(s, both), couple(s, upper)
    n_up = upper.size
    assert np.array_equal(both.nodes[:n_up], upper.nodes)  # the upper sheet's nodes come first
    M = mo.M.toarray()
    scale = np.abs(ref.M).max()
    assert np.abs(M[:, :n_up] - ref.M.toarray()).max() <= 1e-13 * scale
    assert np.abs(M[:, n_up:]).max() <= 1e-13 * scale
    np.testing.assert_allclose(mo.coverage, 1.0, atol=1e-12)


def test_mutation_without_the_nearest_hit_both_sheets_count(monkeypatch):
    def none(s, m, e, f, poly, count, *args):
        return np.ones(e.size), e, f, poly, count

    monkeypatch.setattr(fc, "nearest_hits", none)
    s = surface(flat((1.0, 2.0), (3, 4, 1), HEX, "bottom"), "bottom")
    mo = couple(s, surface(_sheets(TET), "top"))
    assert mo.coverage.min() > 1.9  # each slave face counted twice


def test_a_master_folded_twice_is_refused():
    s = surface(flat((1.0, 2.0), (3, 4, 1), HEX, "bottom"), "bottom")
    with pytest.raises(ValueError, match="folds more than once"):
        couple(s, surface(_sheets(TET, n=3), "top"))
