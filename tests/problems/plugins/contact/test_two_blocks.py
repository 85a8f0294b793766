"""The shipped two-body 3D unilateral scene `two_blocks3d` (two blocks 1e-4 m apart, a tilted
press, Coulomb friction through the 3D dual mortar): the weighted mortar gap of the parallel
faces is the geometric 1e-4 m at every node; the answer has open, stick and slip nodes, does
not penetrate beyond the mortar's weak O(h²) sense when measured on the deformed nodal
positions alone, and semismooth Newton and the fixed point on Tresca problems (independent
paths) agree. Mutation: the two-body gap of the wrong sign is seen by the nodal gap check."""

from __future__ import annotations

import numpy as np
import pytest

import vi_core
from problems.plugins.contact import checks as contact3d_checks
from problems.plugins.contact import solid as contact3d
from problems.plugins.contact import surface_contact
from problems.scene import load_scene

from .test_solid_unilateral import _geometric_gap

GAP = 1.0e-4


def solved(level: int):
    model = contact3d.build(load_scene("two_blocks3d"), level)
    sol = vi_core.solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    return model, sol


@pytest.mark.parametrize("level", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_two_blocks3d(level):
    model, sol = solved(level)
    c = model.contact
    assert np.abs(c.gap0 / c.W[c.rows_n] - GAP).max() <= 1e-10 * GAP
    st = contact3d.contact_state(model, sol)
    assert {"open", "stick", "slip"} <= set(st["state"])
    d = _geometric_gap(model, sol)
    assert np.nanmin(d) >= -0.1 * GAP and np.abs(d[st["touch"]]).max() <= 0.1 * GAP
    assert st["lemma_4_2"] <= 1e-12
    assert max(contact3d_checks.separation(model, sol).values()) <= 1e-10
    fp = vi_core.solve(model.vi, "fixed_point", inner="ssn", tol=1e-12)
    assert fp.converged
    assert np.abs(fp.lam - sol.lam).max() <= 1e-8 * np.abs(sol.lam).max()
    assert np.abs(fp.u - sol.u).max() <= 1e-8 * np.abs(sol.u).max()


def test_a_wrong_sign_of_the_gap_is_seen(monkeypatch):
    real = surface_contact._positions
    monkeypatch.setattr(surface_contact, "_positions", lambda *a: -real(*a))
    model, sol = solved(0)
    d = _geometric_gap(model, sol)
    touch = contact3d.contact_state(model, sol)["touch"]
    assert touch.any() and np.abs(d[touch]).max() > 0.5 * GAP
