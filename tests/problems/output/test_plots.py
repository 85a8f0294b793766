"""Figures people read: shared scales across panels of one quantity, units on every axis, no
internal names, the tangent's sign convention stated (problems.output.plots, mixvi figures)."""

import re

import matplotlib.pyplot as plt
import numpy as np
import pytest

from problems.commands.figures import panel_heading
from problems.output import plots
from problems.scene import load_scene
from vi_core import solve


def _sweep(monkeypatch, tmp_path, plugin_name, scene, key, values):
    """The sweep figure of `scene` over `key` = values at level 0, kept open for inspection."""
    import importlib

    plugin = importlib.import_module(f"problems.plugins.{plugin_name}")
    panels = []
    for v in values:
        model = plugin.build(load_scene(scene, [f"{key}={v!r}"]), 0)
        panels.append((panel_heading("friction bound g [Pa]", v), model, solve(model.vi, "ssn")))
    figs = []
    monkeypatch.setattr(plots.pyplot(), "close", figs.append)  # keep the figure
    plots.sweep_figure(panels, plugin.draw, tmp_path / "f.png", title="t")
    assert (tmp_path / "f.png").is_file()
    return figs[0]


def _by_label(fig):
    out = {}
    for ax in fig.axes:
        out.setdefault(ax.get_ylabel(), []).append(ax.get_ylim())
    return out


CASES = [
    ("contact.plane", "rigid_foundation", "contact.g", (2e7, 9e6, 3e6)),
    ("antiplane", "antiplane", "friction.g", (1.2e6, 8e5, 4.8e5)),
    ("signorini", "signorini", "contact.g", (1e6, 5e5)),
]


@pytest.mark.parametrize(("plugin", "scene", "key", "values"), CASES)
def test_panels_of_one_quantity_share_one_scale(monkeypatch, tmp_path, plugin, scene, key, values):
    fig = _sweep(monkeypatch, tmp_path, plugin, scene, key, values)
    groups = _by_label(fig)
    assert len(groups) == 2  # the multiplier and the jump, each on every panel
    for lims in groups.values():
        assert len(lims) == len(values) and len(set(lims)) == 1
    texts = [t for ax in fig.axes for t in (ax.get_xlabel(), ax.get_ylabel()) if t]
    assert all(re.search(r"\[(m|Pa)\]$", t) for t in texts), texts  # a unit on every axis
    every = texts + [t.get_text() for t in fig.texts] + [ax.get_title() for ax in fig.axes]
    for ax in fig.axes:
        leg = ax.get_legend()
        every += [t.get_text() for t in leg.get_texts()] if leg else []
    prose = [re.sub(r"\$[^$]*\$", "", t) for t in every]  # outside the formulas
    assert not [t for t in prose if re.search(r"[a-z]_[a-z]", t)]  # no lam_t, ut_slave
    notes = [t.get_text() for t in fig.texts if t.get_gid() == plots.NOTE_GID]
    assert len(notes) == 1 and "sign convention" in notes[0]
    assert ("e_z" in notes[0]) == (plugin == "antiplane")  # antiplane's tangent is e_z, not τ
    plt.close(fig)


def test_mutation_without_shared_scales_the_panels_differ(monkeypatch, tmp_path):
    monkeypatch.setattr(plots, "share_scales", lambda fig: None)
    fig = _sweep(monkeypatch, tmp_path, *CASES[0])
    assert any(len(set(lims)) > 1 for lims in _by_label(fig).values())
    plt.close(fig)


def test_share_scales_keeps_different_quantities_apart_and_shares_colour_ranges():
    rng = np.random.default_rng(3)
    fig, ((a, b), (c, d)) = plt.subplots(2, 2)
    a.plot([0, 1], [0, 1])
    a.set_ylabel("stress [Pa]")
    b.plot([0, 1], [0, 1e-3])
    b.set_ylabel("displacement [m]")
    ia = c.imshow(rng.random((3, 3)), label="von Mises stress [Pa]")
    ib = d.imshow(5 + rng.random((3, 3)), label="von Mises stress [Pa]")
    plots.share_scales(fig)
    assert a.get_ylim() != b.get_ylim()
    assert ia.get_clim() == ib.get_clim()
    assert ia.get_clim()[0] < 1 and ia.get_clim()[1] > 5
    plt.close(fig)


def test_panel_headings_carry_the_unit():
    assert panel_heading("friction bound g [Pa]", 1.5e8) == "friction bound g = 1.5e+08 Pa"
    assert panel_heading("load f [1]", -2.0) == "load f = -2"
    assert panel_heading("scale", 3.0) == "scale = 3"


def test_log_axes_share_a_positive_range():
    fig, (a, b) = plt.subplots(1, 2)
    a.loglog([0.1, 0.2], [1e-3, 1e-4])
    b.loglog([0.05, 0.4], [1.0, 2.0])
    for ax in (a, b):
        ax.set_xlabel("mesh size h [m]")
    plots.share_scales(fig)
    assert a.get_xlim() == b.get_xlim()
    lo, hi = a.get_xlim()
    assert 0 < lo < 0.05 and hi > 0.4
    assert a.get_ylim() != b.get_ylim()  # no y labels: not the same quantity
    plt.close(fig)
