"""Unit invariance: a scene written in m/Pa/V and in mm/MPa/kV gives the same physical answer.

Conversions (mm, MPa, kV): lengths and displacements ×1e3, stresses (C, g, tractions) ×1e-6,
potentials ×1e-3, the piezoelectric e (stress·length/potential) ×1, the permittivity κ
(stress·length²/potential²) ×1e6; multiplier coefficients are stresses (×1e-6).
"""

import copy

import numpy as np
import pytest

from problems.plugins.contact import plane as pc
from problems.scene import Scene, load_scene
from problems.scene.materials import NAMED
from vi_core import solve

L, S, V = 1e3, 1e-6, 1e-3  # factors: length, stress, potential


def _piezo_mm(name):
    d = NAMED[name]
    return {
        "kind": "piezoelectric",
        "C": (np.array(d["C"]) * S).tolist(),
        "e": np.array(d["e"]).tolist(),
        "kappa": (np.array(d["kappa"]) * S * L**2 / V**2).tolist(),
    }


def _to_mm(scene: Scene) -> Scene:
    data = copy.deepcopy(scene.data)
    for body in data["bodies"].values():
        geo = body["geometry"]
        for key in ("x", "y", "center", "p2", "p3"):
            if key in geo:
                geo[key] = [v * L for v in geo[key]]
        if "radius" in geo:
            geo["radius"] *= L
        mat = body["material"]
        if isinstance(mat, str):
            body["material"] = _piezo_mm(mat)
        elif mat.get("kind") == "isotropic":
            mat["E"] *= S
        for d in body.get("displacement", []):
            d["value"] = [
                f"{L!r}*({v.replace('x', f'(x/{L!r})')})" if isinstance(v, str) else v * L
                for v in d["value"]
            ]
        for d in body.get("potential", []):
            d["value"] *= V
    data["contact"]["g"] *= S
    return Scene(data, scene.path, scene.name + "_mm")


@pytest.mark.parametrize("name,level", [("rigid_foundation", 1), ("paper_two_body", 1)])
def test_mm_mpa_kv_gives_the_same_physical_answer(name, level):
    si = load_scene(name)
    m1 = pc.build(si, level)
    m2 = pc.build(_to_mm(si), level)
    s1, s2 = solve(m1.vi, "ssn"), solve(m2.vi, "ssn")
    assert s1.converged and s2.converged
    x1, x2 = m1.full(s1.u), m2.full(s2.u)
    for b1, b2 in zip(m1.bodies, m2.bodies, strict=True):
        u1, p1 = b1.split(x1[b1.offset : b1.offset + b1.size])
        u2, p2 = b2.split(x2[b2.offset : b2.offset + b2.size])
        assert np.linalg.norm(u2 / L - u1) <= 1e-8 * np.linalg.norm(u1)
        if p1 is not None:
            assert np.linalg.norm(p2 / V - p1) <= 1e-8 * np.linalg.norm(p1)
    assert np.linalg.norm(s2.lam / S - s1.lam) <= 1e-8 * np.linalg.norm(s1.lam)
    st1, st2 = pc.contact_state(m1, s1), pc.contact_state(m2, s2)
    assert (st1["slip"] == st2["slip"]).all()
    assert s1.iterations == s2.iterations
