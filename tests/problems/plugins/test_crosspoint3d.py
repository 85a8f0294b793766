"""The 3D crosspoint basis `[contact] ends = "merge"` against 2D, which merges by default.

rigid_foundation (2D) and its extrusion with the left side clamped to a displacement (not 0,
so that the merged rows' entries at the clamped nodes reach the gap; a friction bound that
rises towards it): the contact nodes on the
left edge carry no multiplier; 2D gives their dual functions to their neighbours (Wohlmuth),
3D with "merge" does the same class by class, and the extruded answer is the 2D one to
rounding. "keep" and the faults (the merge dropped in one class, a wrong share) do not
reproduce it.
"""

from __future__ import annotations

import pytest

import fem.mortar3d as fm3
import vi_core
from problems.plugins import contact3d
from problems.plugins import piezo_contact as pc
from problems.scene import load_scene

from .test_contact3d import EXTRUDED, _against_2d

LEFT = [-1.0e-4, -1.0e-4]  # the clamped left side's displacement (2D; 3D adds u_z = 0)
# a friction bound rising towards the clamped side, so that the node next to it sticks (a
# slipping node's row is blind to its gap) and the bounds ∫gφ̃_k / ∫φ̃_k vary
G = "contact.g=9e6*(1+10*(1-x/2)**4)"  # degree 4: both quadratures exact


def _clamped(name: str, value: list[float], overrides=()):
    scene = load_scene(name, [G, *overrides])
    scene.data["bodies"]["block"]["displacement"].append({"boundary": "left", "value": value})
    return scene


def _pair(level: int, ends: str):
    m2 = pc.build(_clamped("rigid_foundation", LEFT), level)
    s2 = vi_core.solve(m2.vi, method="ssn", tol=1e-12)
    m3 = contact3d.build(_clamped(EXTRUDED, [*LEFT, 0.0], [f"contact.ends={ends}"]), level)
    s3 = vi_core.solve(m3.vi, method="ssn", tol=1e-12)
    assert m2.contact.ends == "merge" and s2.converged and s3.converged
    return m2, s2, m3, s3


def test_merge_reproduces_the_2d_solution_with_a_clamped_end_and_keep_does_not():
    m2, s2, m3, s3 = _pair(0, "merge")
    c = m3.contact
    assert c.ends == "merge" and c.surf.size - c.rows_n.size == 3  # the left edge's nodes
    d = _against_2d(m2, s2, m3, s3)
    assert max(d.values()) < 1e-11, d
    st = contact3d.contact_state(m3, s3)
    assert st["lemma_4_2"] < 1e-12, st["lemma_4_2"]
    assert st["slip"].any() and (st["state"] == "stick").any()
    _, _, k3, t3 = _pair(0, "keep")
    assert max(_against_2d(m2, s2, k3, t3).values()) > 1e-6


def _one_class(monkeypatch, cls: str):
    """The merge dropped in one class: that class's basis is built with "keep"."""
    real = contact3d.class_blocks
    calls = []

    def faulty(surf, carry, covered, ends, M_loc=None):
        calls.append(ends)
        which = "normal" if len(calls) % 2 == 1 else "tangential"  # slave_contact's order
        return real(surf, carry, covered, "keep" if which == cls else ends, M_loc)

    monkeypatch.setattr(contact3d, "class_blocks", faulty)


def _wrong_share(monkeypatch):
    """A dropped node's function given twice over (shares sum to 2, not 1)."""
    real = fm3.multiplier_basis

    def faulty(s, carry, ends="merge"):
        Q, K = real(s, carry, ends), real(s, carry, "keep")
        return K + 2.0 * (Q - K)

    monkeypatch.setattr(contact3d, "multiplier_basis", faulty)


@pytest.mark.parametrize("fault", ["normal class kept", "tangential class kept", "wrong share"])
def test_each_merge_fault_breaks_the_2d_reproduction(monkeypatch, fault):
    if fault == "wrong share":
        _wrong_share(monkeypatch)
    else:
        _one_class(monkeypatch, fault.split()[0])
    m2, s2, m3, s3 = _pair(0, "merge")
    assert max(_against_2d(m2, s2, m3, s3).values()) > 1e-6
