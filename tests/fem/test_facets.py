"""Traces (fem.facets) on boundary parts: weights, normals, tangent frames, dual basis, facet
integrals; 3D surfaces and 2D chains."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fem.facets as ff
from fem import assembly
from fem.elements import reference_element
from fem.facets import facet_integrals, frames, reference_direction, trace
from fem.mesh import Mesh
from fem.meshing import box, transform
from fem.shapes import half_disc

SEEDS = st.integers(0, 2**31 - 1)


def _wavy(rng, element="hexahedron", level=0):
    """A unit box whose nodes are moved by a smooth random map (curved faces)."""
    a = rng.uniform(-0.08, 0.08, size=(3, 3))
    a[2] = rng.uniform(0.05, 0.1, size=3) * rng.choice([-1.0, 1.0], size=3)  # curved z
    k = rng.uniform(1.0, 2.5, size=3)

    def move(p):
        q = p.copy()
        for i in range(3):
            q[:, i] += (
                a[i, 0] * np.sin(k[0] * p[:, 1])
                + a[i, 1] * np.cos(k[1] * p[:, 2])
                + a[i, 2] * np.sin(k[2] * p[:, 0])
            )
        return q

    return transform(box((0, 1), (0, 1), (0, 1), (2, 2, 2), element, level), move)


@settings(max_examples=6)
@given(seed=SEEDS, element=st.sampled_from(["hexahedron", "tetra"]))
def test_weights_sum_to_the_area_and_the_normals_close_up(seed, element):
    """Σ W = the area (by facet_integrals of 1, and by the faces' own areas); nodal normals are
    unit vectors pointing out of every adjacent face."""
    mesh = _wavy(np.random.default_rng(seed), element)
    surf = trace(mesh, list(mesh.boundaries))
    area = surf.measures.sum()
    assert abs(surf.weights.sum() - area) <= 1e-12 * area
    assert abs(facet_integrals(mesh, surf, lambda x, y, z: np.ones_like(x)).sum() - area) <= 1e-12
    # nodal normals: unit, outward (positive on every adjacent face's normal at its centre)
    assert np.allclose(np.linalg.norm(surf.normals, axis=1), 1.0)
    F = mesh.points[surf.nodes[surf.facets]]  # (n_f, k, 3)
    c = F.mean(axis=1)
    fn = np.cross(F[:, 1] - F[:, 0], F[:, -1] - F[:, 0])  # (n_f, 3) outward (counterclockwise)
    inside = np.array([0.5, 0.5, 0.5])
    assert ((fn * (c - inside)).sum(axis=1) > 0).all()  # the faces are oriented outward
    for a in range(surf.facets.shape[1]):
        assert (np.einsum("ij,ij->i", surf.normals[surf.facets[:, a]], fn) > 0).all()


@settings(max_examples=6)
@given(seed=SEEDS, element=st.sampled_from(["hexahedron", "tetra"]))
def test_dual_basis_is_biorthogonal_on_curved_faces(seed, element):
    """∫_e ψ_{e,a} φ_b dA = δ_ab ∫_e φ_a dA on every face, checked by a finer quadrature."""
    mesh = _wavy(np.random.default_rng(seed), element)
    surf = trace(mesh, "bottom")
    A = surf.dual  # (n_f, k, k)
    ref = reference_element(surf.facet_type)
    pts, w = ref.quadrature(8 if surf.facet_type == "quad" else 5)
    phi = ref.values(pts)  # (q, k)
    F = mesh.points[surf.nodes[surf.facets]]  # (n_f, k, 3)
    T = np.einsum("fai,qaj->fqij", F, ref.gradients(pts))
    dA = np.linalg.norm(np.cross(T[..., 0], T[..., 1]), axis=-1) * w  # (n_f, q)
    psi = np.einsum("fab,qb->fqa", A, phi)  # (n_f, q, k)
    got = np.einsum("fq,fqa,qb->fab", dA, psi, phi)
    want = np.einsum("fq,qa->fa", dA, phi)[:, :, None] * np.eye(phi.shape[1])
    assert np.abs(got - want).max() <= 1e-6 * dA.sum(axis=1).max()


@settings(max_examples=8)
@given(seed=SEEDS)
def test_frames_are_orthonormal_right_handed_and_continuous(seed):
    """(t1, t2, n) orthonormal with t1 × t2 = n; on a curved surface the largest turn of t1
    between neighbouring nodes halves with the mesh size (continuity)."""
    turns = []
    for level in (1, 2):
        mesh = _wavy(np.random.default_rng(seed), "hexahedron", level)
        surf = trace(mesh, "bottom")
        t1, t2 = frames(surf.normals)
        F = np.stack([t1, t2, surf.normals], axis=1)
        assert np.abs(F @ F.transpose(0, 2, 1) - np.eye(3)).max() < 1e-12
        assert np.abs(np.cross(t1, t2) - surf.normals).max() < 1e-12
        e = surf.edges()
        turns.append(
            np.arccos(np.clip(np.einsum("ij,ij->i", t1[e[:, 0]], t1[e[:, 1]]), -1, 1)).max()
        )
    assert turns[1] < 0.65 * turns[0] + 1e-12


def test_frame_of_a_flat_side_and_the_refusal_of_a_turning_surface():
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1))
    surf = trace(mesh, "front")  # y = 0: n = −e_y
    t1, t2 = frames(surf.normals)
    assert np.allclose(surf.normals, [0, -1, 0]) and np.allclose(t1, [1, 0, 0])
    assert np.allclose(t2, [0, 0, 1])
    with pytest.raises(ValueError, match="turn too far"):
        reference_direction(np.eye(3))


def test_mutation_a_wrong_sign_in_the_frame_is_caught():
    """t2 = t1 × n (the wrong order) breaks the handedness check above."""
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1))
    surf = trace(mesh, "bottom")
    t1, _ = frames(surf.normals)
    bad = np.cross(t1, surf.normals)
    assert np.abs(np.cross(t1, bad) - surf.normals).max() > 1.0


# ---------------------------------------------------------------- 2D chains of segments
def _generic_segment_data(mesh, tr, order=4):
    """Mass matrices, ∫φ_a, ∫φ_a n and A_e = D_e M_e⁻¹ of the trace's segments by the generic
    quadrature of `fem.facets` (the path of 3D faces), to check the closed forms of 2D."""
    x = mesh.points[tr.nodes[tr.facets]]  # (n_seg, 2, 2)
    pts, w = reference_element("line").quadrature(order)  # (q, 1), (q,)
    phi = ff.facet_values("line", pts)  # (q, 2)
    d = x[:, 1] - x[:, 0]  # (n_seg, 2)
    L = np.linalg.norm(d, axis=1)
    mass = np.einsum("e,q,qa,qb->eab", L, w, phi, phi)  # (n_seg, 2, 2)
    fw = mass.sum(axis=2)
    n = np.stack([d[:, 1], -d[:, 0]], axis=1)  # (n_seg, 2) outward, × L
    nloc = np.einsum("q,qa,ei->eai", w, phi, n)  # (n_seg, 2, 2) ∫_e φ_a n
    nsum = np.zeros((tr.size, 2))
    np.add.at(nsum, tr.facets.ravel(), nloc.reshape(-1, 2))
    return fw, nsum / np.linalg.norm(nsum, axis=1)[:, None], fw[:, :, None] * np.linalg.inv(mass)


def _check_closed_forms(seed: int) -> None:
    """On a perturbed half disc (a curved chain with uneven segments) the closed forms of a 2D
    trace — ∫φ_a = |e|/2, the length-weighted normals, A_e = [[2, −1], [−1, 2]] — are the
    face formulas of 3D (D_e M_e⁻¹, n_k ∝ ∫φ_k n) applied to segments."""
    rng = np.random.default_rng(seed)
    mesh = half_disc(level=1)
    pts = mesh.points + rng.uniform(-0.02, 0.02, mesh.points.shape)
    mesh = Mesh(pts, mesh.cells, mesh.boundaries)
    tr = trace(mesh, "contact")
    fw, normals, dual = _generic_segment_data(mesh, tr)
    np.testing.assert_allclose(tr.facet_weights, fw, rtol=1e-14)
    np.testing.assert_allclose(tr.normals, normals, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.dual, dual, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.bincount(tr.facets.ravel(), fw.ravel()), tr.weights, rtol=1e-14)


@settings(max_examples=6)
@given(seed=SEEDS)
def test_segment_closed_forms_agree_with_the_face_formulas(seed):
    """`_check_closed_forms` on random perturbations."""
    _check_closed_forms(seed)


def test_mutation_a_wrong_segment_dual_is_caught(monkeypatch):
    """A_e = I (the primal basis) on segments: the comparison above fails."""
    monkeypatch.setattr(ff, "SEGMENT_DUAL", np.eye(2))
    with pytest.raises(AssertionError):
        _check_closed_forms(0)


def test_segment_tangents_arc_length_sizes_and_integrals():
    """2D: τ = (−n_y, n_x) (`frames`, `Trace.tangents`), s the arc length, node sizes the longer
    adjacent segment, facet integrals summed per node = `fem.assembly.boundary_load`; arc
    length is refused on a 3D surface."""
    mesh = half_disc(level=1)
    tr = trace(mesh, "contact")
    (tau,) = frames(tr.normals)
    assert np.array_equal(tau, tr.tangents)
    np.testing.assert_allclose(np.einsum("ki,ki->k", tau, tr.normals), 0.0, atol=1e-15)
    n = tr.normals
    assert (n[:, 0] * tau[:, 1] - n[:, 1] * tau[:, 0] > 0).all()  # (n, τ) right-handed
    np.testing.assert_allclose(np.diff(tr.s), tr.measures[: tr.size - 1], rtol=1e-14)
    h = np.maximum(np.r_[tr.measures, 0.0], np.r_[0.0, tr.measures])[: tr.size]
    np.testing.assert_array_equal(tr.node_sizes(), h)  # an open chain: k − 1 segments

    def f(x, y):
        return 1.0 + x * y - y**2

    per_node = np.bincount(tr.facets.ravel(), facet_integrals(mesh, tr, f).ravel(), tr.size)
    ref = assembly.boundary_load(mesh, "contact", f, 1)[tr.nodes]
    np.testing.assert_allclose(per_node, ref, rtol=1e-13)
    with pytest.raises(ValueError, match="2D trace"):
        _ = trace(box((0, 1), (0, 1), (0, 1), (1, 1, 1)), "bottom").s
