"""Bilateral contact of two bodies closes any initial gap between them (up to the admitted
SEPARATION_TOL·h): summary.json says how large it was (contact.initial_gap_closed) and a
warning names it when it is not small against the contact displacement."""

from __future__ import annotations

import json

import pytest

import problems
from problems.plugins.contact import output, separation

SCENE = "shear_strip_two_body"  # the base's top at y = 0, touching the block's bottom


def _closed(gap: float):
    res = problems.solve_scene(SCENE, level=0, bodies__base__geometry__y=[-0.5, -gap])
    entry = output.closed_gap_summary(res.model, res.solution)["initial_gap_closed"]
    return entry, output.closed_gap_warning(res.model, res.solution)


def test_a_real_gap_is_measured_and_warned_of():
    entry, warnings = _closed(1e-3)  # displacements ~1e-3 m: closing 1 mm changes the answer
    assert entry["max"] == pytest.approx(1e-3, rel=1e-9)
    assert entry["relative_to_displacement"] > output.CLOSED_GAP_TOL
    assert len(warnings) == 1 and "law = 'unilateral'" in warnings[0] and "0.001 m" in warnings[0]


def test_coincident_interfaces_and_a_tiny_gap_are_not_warned_of():
    entry, warnings = _closed(0.0)
    assert entry["max"] == 0.0 and not warnings
    entry, warnings = _closed(1e-6)
    assert entry["max"] == pytest.approx(1e-6, rel=1e-6) and not warnings


def test_the_gap_and_its_warning_reach_summary_json(tmp_path):
    res = problems.solve_scene(SCENE, level=0, bodies__base__geometry__y=[-0.5, -1e-3])
    res.write(tmp_path / "o")
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["contact"]["initial_gap_closed"]["max"] == pytest.approx(1e-3, rel=1e-9)
    assert any("bilateral law closes that gap" in w for w in s["warnings"])


def test_mutation_an_unmeasured_gap_is_caught(monkeypatch):
    real = separation.separation

    def coincident(*a, **kw):  # the distances dropped: every node on the master
        t, h = real(*a, **kw)
        return t * 0.0, h

    monkeypatch.setattr(separation, "separation", coincident)
    with pytest.raises(AssertionError):
        test_a_real_gap_is_measured_and_warned_of()
