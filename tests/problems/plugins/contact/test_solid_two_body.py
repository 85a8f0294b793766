"""Two-body 3D contact (contact3d with the 3D dual mortar of fem.mortar): the paper's example
extruded reproduces the 2D two-body solution (piezo_contact, paper_two_body) to rounding,
multipliers included; the spherical cap in a piezo pad (non-matching curved surfaces) solves
with a rigid-body patch defect at rounding level in summary.json — and the checks fail when
the mortar is broken."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fem.clipping as fc
import problems
from problems.commands import main as cli
from problems.errors import SceneError
from problems.plugins.contact import solid as contact3d
from problems.scene import load_scene

EXTRUDED = "paper_two_body_extruded"
CAP = "spherical_cap"


def _solve(name: str, level: int, **overrides):
    return problems.solve_scene(problems.load_scene(name), level=level, tol=1e-12, **overrides)


def _extruded_against_2d(level: int, layers: int) -> dict[str, float]:
    """Relative max differences of the extruded 3D answer from the 2D one, node by node."""
    r3 = _solve(EXTRUDED, level, bodies__disc__geometry__layers=layers,
                bodies__cradle__geometry__layers=layers)  # fmt: skip
    r2 = _solve("paper_two_body", level)
    out = {}
    for key in ("disc.displacement", "cradle.displacement", "cradle.potential"):
        a2, a3 = r2.fields[key], r3.fields[key]
        a3 = a3.reshape(-1, a2.shape[0], *a3.shape[1:])  # (layers + 1, N, ...): i + l·N ↔ i
        if a3.ndim == 3:
            out[key + ".z"] = float(np.abs(a3[..., 2]).max() / np.abs(a2).max())
            a3 = a3[..., :2]
        out[key] = float(np.abs(a3 - a2[None]).max() / np.abs(a2).max())
    c3, c2 = r3.model.contact, r3.contact
    n2d = r2.model.bodies[0].mesh.n_nodes
    slave2 = r2.model.contact.tr.nodes  # 2D trace nodes (global ids of the disc)
    k = np.searchsorted(np.sort(slave2), c3.tr.nodes % n2d)
    where = np.argsort(slave2)[k]  # 3D surface node → 2D trace index
    lam_n2, lam_t2 = r2.contact["lambda_n"][where], r2.contact["lambda_t"][where]
    tau = r2.model.contact.tr.tangents[where]  # (k, 2) the 2D tangent of each 3D node
    lam_t3 = np.einsum("ki,ki->k", c2["lambda_t_vec"][:, :2], tau)
    scale = np.abs(lam_n2).max()
    out["lam_n"] = float(np.abs(c2["lambda_n"] - lam_n2).max() / scale)
    out["lam_t"] = float(np.abs(lam_t3 - lam_t2).max() / scale)
    out["slip"] = float(((c2["state"] == "slip") != (r2.contact["state"][where] == "slip")).sum())
    out["patch_defect"] = c3.patch_defect
    return out


@pytest.mark.parametrize("layers", [1, 2])
def test_extruded_paper_example_reproduces_the_2d_two_body_solution(layers):
    """Plane strain (u_z = 0 on both ends), the 2D meshes extruded: u, φ, λ_n, λ_t and the
    stick/slip states of the 2D solution to rounding (measured ≤ 1e-14 relative)."""
    d = _extruded_against_2d(0, layers)
    for key, v in d.items():
        assert v <= 1e-12, (key, d)


def test_mutation_plane_normal_projection_breaks_the_extruded_reproduction(monkeypatch):
    """The textbook auxiliary-plane projection (constant normal per face) is a different
    coupling: the 3D answer leaves the 2D one far above rounding."""
    monkeypatch.setattr(fc, "_rays", lambda face_type, X, y, xi, **kw: xi)
    d = _extruded_against_2d(0, 1)
    assert d["cradle.displacement"] > 1e-6 and d["patch_defect"] <= 1e-12, d


def test_spherical_cap_in_a_piezo_pad(tmp_path):
    """The truly 3D scene: non-matching hexahedra and tetrahedra on a spherical contact
    surface; converges, the patch defect in summary.json is at rounding level, stick and slip
    both occur, and the Lemma 4.2 identity holds."""
    out = tmp_path / "cap"
    code = cli.main(["solve", CAP, "--level", "0", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    c = summary["contact"]
    assert c["master"] == "pad"
    assert c["mortar_patch_defect"] <= 1e-12
    assert c["uncovered_nodes"] == []
    assert c["stick"] > 0 and c["slip"] > 0, c["counts"]
    assert summary["lemma_4_2"] <= 1e-8


def test_mutation_dropped_cell_is_seen(monkeypatch):
    """A dropped integration cell leaves its slave face partly uncovered: the nodes of that
    face lose their multipliers (so the patch defect of the rows kept stays at rounding) and
    are listed as uncovered, which the unbroken scene has none of."""
    real = fc.cells

    def drop(*args, **kw):
        e, f, poly, count, *rest = real(*args, **kw)
        keep = np.arange(e.size) != e.size // 2
        return (e[keep], f[keep], poly[keep], count[keep], *rest)

    monkeypatch.setattr(fc, "cells", drop)
    m = contact3d.build(load_scene(CAP), 0)
    assert (~m.contact.covered).sum() >= 3  # the nodes of one face
    assert m.contact.patch_defect <= 1e-12


def test_master_must_be_another_body():
    with pytest.raises(SceneError, match="a body other than the slave"):
        problems.load_scene(EXTRUDED, contact__master="disc.top")
    with pytest.raises(SceneError, match="contact.master"):
        problems.load_scene(EXTRUDED, contact__master="cradle.nowhere")


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ("contact.master=base.bottom", "face the same way"),
        ("bodies.top.geometry.z=[-1.0,-0.5]", "face away from each other"),
        ("bodies.top.geometry.x=[3.0,4.0]", "do not overlap seen along the slave's normal"),
    ],
    ids=["same-way", "facing-away", "beside"],
)
def test_surfaces_that_do_not_face_each_other_are_named_as_such(tmp_path, capsys, change, why):
    """Two 3D bodies whose contact surfaces do not face each other (issue 29): exit 2 with one
    line naming contact.master and what is wrong — not "displacement not fully prescribed"."""
    out = tmp_path / "o"
    assert cli.main(["solve", "two_blocks3d", "--set", change, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "contact.master" in err[0], err
    assert why in err[0] and "no slave node has this master behind its faces" in err[0], err
    assert "prescribed" not in err[0] and not out.exists()
