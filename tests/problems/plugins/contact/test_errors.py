"""The 3D error norms against a finer level (`errors.reference_errors`) on a scene of two
bodies: ``u_nodes`` is the relative RMS difference over the coarse nodes of every body, pooled
(Σ_bodies Σ_nodes |u_h − u_ref|² over Σ_bodies Σ_nodes |u_ref|²), recomputed here from the
nodal fields by name with a k-d tree match of the nested nodes. Mutation (the defect this file
was written for): a value overwritten per body (the last body's alone) is seen."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

import vi_core
from problems.plugins.contact import errors, solid
from problems.plugins.contact import model as contact_model
from problems.scene import load_scene


@pytest.fixture(scope="module")
def two_levels():
    out = []
    for level in (0, 1):
        model = solid.build(load_scene("two_blocks3d"), level)
        sol = vi_core.solve(model.vi, "ssn", tol=1e-10)
        assert sol.converged
        out += [model, sol]
    return out


def _per_body(model, sol, ref, ref_sol) -> dict[str, tuple[float, float]]:
    """Per body: (Σ |u_h − u_ref|², Σ |u_ref|²) over its coarse nodes."""
    coarse, fine = contact_model.fields(model, sol), contact_model.fields(ref, ref_sol)
    out = {}
    for b, bf in zip(model.bodies, ref.bodies, strict=True):
        dist, idx = cKDTree(bf.mesh.points).query(b.mesh.points)
        assert dist.max() <= 1e-12  # nested meshes: every coarse node is a fine one
        u_ref = fine[f"{b.name}.displacement"][idx]  # (N, 3)
        diff = coarse[f"{b.name}.displacement"] - u_ref
        out[b.name] = (float(np.sum(diff**2)), float(np.sum(u_ref**2)))
    return out


def test_u_nodes_pools_every_body(two_levels):
    model, sol, ref, ref_sol = two_levels
    per = _per_body(model, sol, ref, ref_sol)
    assert len(per) == 2
    alone = {k: np.sqrt(d / r) for k, (d, r) in per.items()}
    assert abs(alone["top"] - alone["base"]) > 0.1 * max(alone.values())  # they differ
    pooled = np.sqrt(sum(d for d, _ in per.values()) / sum(r for _, r in per.values()))
    got = errors.reference_errors(solid.contact_state, model, sol, ref, ref_sol)
    assert got["u_nodes"] == pytest.approx(pooled, rel=1e-12)
    assert "phi_nodes" not in got  # no piezoelectric body
