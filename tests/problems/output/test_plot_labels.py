"""What the contact plots and tables say: φ along arc length, the nodes counted by their
labels (open is not stick), the friction bound named for its law (±g, ±F·λ_n), readable
coordinates of a 3D contact map."""

from __future__ import annotations

import numpy as np
import pytest

from problems.commands.main import main
from problems.output import plots
from problems.output.results import ContactTable


@pytest.mark.parametrize(
    ("v", "label"),
    [
        ([1.0, 0.0, 0.0033], "x [m]"),
        ([0.0, -1.0, 0.0], "−y [m]"),
        ([2**-0.5, 0.0, 2**-0.5], "0.71 x + 0.71 z [m]"),
        ([0.6, -0.8, 0.0], "0.6 x − 0.8 y [m]"),
        ([-0.6, 0.0, 0.8], "−0.6 x + 0.8 z [m]"),
    ],
)
def test_direction_labels_read_as_coordinates(v, label):
    assert plots.direction_label(v) == label


def _state(labels, friction=None):
    labels = np.array(labels)
    k = labels.size
    st = {
        "s": np.linspace(0.0, 1.0, k),
        "lam_t": np.zeros(k),
        "g": np.ones(k),
        "jump_t": np.zeros(k),
        "ut_slave": np.zeros(k),
        "slip": labels == "slip",
        "state": labels,
    }
    if friction:
        st["friction"] = friction
    return st


def _figures(monkeypatch) -> list:
    """The figures plots closes (recorded instead of dropped)."""
    seen = []
    monkeypatch.setattr(plots.pyplot(), "close", seen.append)
    return seen


def test_the_contact_plot_counts_open_nodes_as_open_and_names_coulombs_bound(tmp_path, monkeypatch):
    seen = _figures(monkeypatch)
    st = _state(["stick", "open", "open", "slip", "ambiguous"], "coulomb")
    plots.contact_plots(st, tmp_path, title="t")
    ax = seen[0].axes[0]
    assert ax.get_title() == "t: stick 1, slip 1, open 2, ambiguous 1 nodes"
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert r"friction bound $\pm F\lambda_n$" in legend and not any("pm g" in t for t in legend)
    seen.clear()
    plots.contact_plots(_state(["stick", "slip"]), tmp_path, title="t")  # Tresca: ±g
    legend = [t.get_text() for t in seen[0].axes[0].get_legend().get_texts()]
    assert r"friction bound $\pm g$" in legend


def test_mutation_without_the_labels_open_counts_as_stick():
    st = _state(["stick", "open", "open", "slip"])
    assert plots.state_counts(st) == "stick 1, slip 1, open 2"
    del st["state"]  # what the plot counted before: every node not slipping
    assert plots.state_counts(st) != "stick 1, slip 1, open 2"


def test_the_potential_is_plotted_along_arc_length(tmp_path, monkeypatch):
    """A vertical side (x constant): φ against s, not a vertical line at x."""
    seen = _figures(monkeypatch)
    y = np.array([0.0, 0.1, 0.3, 0.6])
    points = np.stack([np.full(4, 2.0), y], axis=1)
    phi = np.array([0.0, 1.0, 2.0, 4.0])
    plots.potential_plot(points, y, phi, tmp_path, "body.right")
    line = seen[0].axes[0].get_lines()[0]
    assert np.array_equal(line.get_xdata(), y) and np.array_equal(line.get_ydata(), phi)
    assert seen[0].axes[0].get_xlabel() == "arc length along body.right [m]"


def test_table_meanings_name_the_bound_of_the_friction_law():
    k = 2
    kw = dict(
        points=np.zeros((k, 2)),
        normals=np.tile([0.0, 1.0], (k, 1)),
        weights=np.ones(k),
        segments=np.array([[0, 1]]),
        lambda_n=np.ones(k),
        lambda_t=np.zeros(k),
        jump_t=np.zeros(k),
        state=np.array(["stick", "open"]),
    )
    coulomb = ContactTable(**kw, friction="coulomb")
    tresca = ContactTable(**kw)
    for col in ("lambda_t", "state"):
        assert "F lambda_n" in coulomb.meaning(col) and "= g" not in coulomb.meaning(col)
        assert "= g" in tresca.meaning(col) and "lambda_n)" not in tresca.meaning(col)


@pytest.mark.parametrize("scene", ["coulomb_strip", "coulomb_strip3d"])
def test_coulomb_scenes_csv_headers_and_legend_say_f_lambda_n(tmp_path, capsys, monkeypatch, scene):
    seen = _figures(monkeypatch)
    out = tmp_path / "o"
    assert main(["solve", scene, "--level", "0", "--out", str(out)]) in (0, 1)
    legends = [
        t.get_text()
        for f in seen
        for ax in f.axes
        if ax.get_legend()
        for t in ax.get_legend().get_texts()
    ]
    assert not any("pm g" in t for t in legends)
    if scene == "coulomb_strip":  # the 2D plot of λ·τ and its bound
        assert r"friction bound $\pm F\lambda_n$" in legends
    header = [ln for ln in (out / "contact.csv").read_text().splitlines() if ln.startswith("#")]
    text = "\n".join(header)
    assert "F lambda_n" in text and "<= g" not in text and "< g)" not in text


@pytest.mark.parametrize("words", [5, 40, 80])
def test_the_foot_note_fits_the_figure_and_clears_the_axes(words):
    """The note is broken into lines inside the figure's width, and the axes (their tick labels
    and x label) end above it: before, a long convention ran off both sides of the PNG."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot([0, 1], [0, 1])
    ax.set_xlabel("arc length along the contact boundary [m]")
    plots.add_note(fig, " ".join(["convention"] * words))
    plots._finish(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    (note,) = [t for t in fig.texts if t.get_gid() == plots.NOTE_GID]
    box, page = note.get_window_extent(renderer), fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0, (box, page)
    assert ax.get_tightbbox(renderer).y0 > box.y1  # nothing of the axes on the note
    plt.close(fig)
