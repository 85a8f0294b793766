"""Traces of 3D meshes on boundary surfaces: weights, normals, tangent frames, dual basis."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fem.elements import reference_element
from fem.meshing import box, transform
from fem.surface3d import face_integrals, frames, reference_direction, surface, triangle_rule

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
    """Σ W = the area (by face_integrals of 1, and by the faces' own areas); nodal normals are
    unit vectors pointing out of every adjacent face."""
    mesh = _wavy(np.random.default_rng(seed), element)
    surf = surface(mesh, list(mesh.boundaries))
    area = surf.areas.sum()
    assert abs(surf.weights.sum() - area) <= 1e-12 * area
    assert abs(face_integrals(mesh, surf, lambda x, y, z: np.ones_like(x)).sum() - area) <= 1e-12
    # nodal normals: unit, outward (positive on every adjacent face's normal at its centre)
    assert np.allclose(np.linalg.norm(surf.normals, axis=1), 1.0)
    F = mesh.points[surf.nodes[surf.faces]]  # (n_f, k, 3)
    c = F.mean(axis=1)
    fn = np.cross(F[:, 1] - F[:, 0], F[:, -1] - F[:, 0])  # (n_f, 3) outward (counterclockwise)
    inside = np.array([0.5, 0.5, 0.5])
    assert ((fn * (c - inside)).sum(axis=1) > 0).all()  # the faces are oriented outward
    for a in range(surf.faces.shape[1]):
        assert (np.einsum("ij,ij->i", surf.normals[surf.faces[:, a]], fn) > 0).all()


@settings(max_examples=6)
@given(seed=SEEDS, element=st.sampled_from(["hexahedron", "tetra"]))
def test_dual_basis_is_biorthogonal_on_curved_faces(seed, element):
    """∫_e ψ_{e,a} φ_b dA = δ_ab ∫_e φ_a dA on every face, checked by a finer quadrature."""
    mesh = _wavy(np.random.default_rng(seed), element)
    surf = surface(mesh, "bottom")
    A = surf.dual  # (n_f, k, k)
    ref = reference_element(surf.face_type)
    pts, w = ref.quadrature(8 if surf.face_type == "quad" else 5)
    phi = ref.values(pts)  # (q, k)
    F = mesh.points[surf.nodes[surf.faces]]  # (n_f, k, 3)
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
        surf = surface(mesh, "bottom")
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
    surf = surface(mesh, "front")  # y = 0: n = −e_y
    t1, t2 = frames(surf.normals)
    assert np.allclose(surf.normals, [0, -1, 0]) and np.allclose(t1, [1, 0, 0])
    assert np.allclose(t2, [0, 0, 1])
    with pytest.raises(ValueError, match="turn too far"):
        reference_direction(np.eye(3))


def test_mutation_a_wrong_sign_in_the_frame_is_caught():
    """t2 = t1 × n (the wrong order) breaks the handedness check above."""
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1))
    surf = surface(mesh, "bottom")
    t1, _ = frames(surf.normals)
    bad = np.cross(t1, surf.normals)
    assert np.abs(np.cross(t1, bad) - surf.normals).max() > 1.0


def test_triangle_rule_degree():
    for order in (3, 5, 10):
        pts, w = triangle_rule(order)
        for i in range(order + 1):
            for j in range(order + 1 - i):  # ∫ s^i t^j = i! j! / (i + j + 2)!
                exact = np.prod(np.arange(1, i + 1)) * np.prod(np.arange(1, j + 1))
                exact /= np.prod(np.arange(1, i + j + 3))
                assert abs(w @ (pts[:, 0] ** i * pts[:, 1] ** j) - exact) <= 1e-15
