"""Tests of fem.shapes: the paper's half disc (slave) and cradle (master)."""

import numpy as np
import pytest

from fem.facets import trace
from fem.shapes import contact_ends, cradle, half_disc

CENTER, R, ANGLE = np.array([0.0, 1.5]), 1.0, np.pi / 2
LEVELS = range(4)


def cell_areas(m):
    P = m.points[m.cells]  # (n_cells, 4, 2)
    x, y = P[..., 0], P[..., 1]
    return 0.5 * (x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y).sum(1)


def max_angle_deg(m):
    P = m.points[m.cells]  # (n_cells, 4, 2)
    a, b = np.roll(P, -1, 1) - P, np.roll(P, 1, 1) - P
    cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1))).max()


def cradle_area():
    Cl, Cr = contact_ends(CENTER, R, ANGLE)
    P = np.array([[-1.0, 0.0], [1.0, 0.0], Cr, Cl])
    poly = 0.5 * np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1])
    return poly - 0.5 * R**2 * (ANGLE - np.sin(ANGLE))


@pytest.mark.parametrize("make, exact", [(half_disc, np.pi * R**2 / 2), (cradle, cradle_area())])
def test_area_converges_at_rate_two(make, exact):
    meshes = [make(level=L) for L in LEVELS]
    errs = [abs(cell_areas(m).sum() - exact) for m in meshes]
    rate_h = np.polyfit(np.log([m.h for m in meshes]), np.log(errs), 1)[0]  # err ~ h^rate
    rate_level = -np.polyfit(np.arange(len(errs)), np.log2(errs), 1)[0]  # err ~ 2^(-rate·L)
    assert 1.9 < rate_level < 2.1, rate_level
    assert 1.9 < rate_h < 2.1, rate_h


@pytest.mark.parametrize("make", [half_disc, cradle])
@pytest.mark.parametrize("level", LEVELS)
def test_cells_are_counterclockwise_and_not_flat(make, level):
    m = make(level=level)
    assert m.cell_type == "quad"
    assert (cell_areas(m) > 0).all()
    assert max_angle_deg(m) < 150.0


@pytest.mark.parametrize("level", LEVELS)
def test_contact_arcs_lie_on_the_circle_with_exact_ends(level):
    Cl, Cr = contact_ends(CENTER, R, ANGLE)
    for m, n_seg, ends in (
        (half_disc(level=level), 8, (Cl, Cr)),
        (cradle(level=level), 12, (Cr, Cl)),
    ):
        t = trace(m, "contact")
        assert t.facets.shape[0] == n_seg * 2**level
        P = m.points[t.nodes]  # (k, 2)
        np.testing.assert_allclose(np.linalg.norm(P - CENTER, axis=1), R, atol=1e-13, rtol=0)
        np.testing.assert_array_equal(P[0], ends[0])
        np.testing.assert_array_equal(P[-1], ends[1])


@pytest.mark.parametrize("angle", [0.1, 0.5, 1.0, 1.5, 2.0, 2.5, 2.8, 3.0, 3.1])
def test_any_opening_below_pi_gives_valid_meshes_with_shared_contact_ends(angle):
    """Wide arcs (up to 3.1 rad) stay meshable: counterclockwise cells, convex (angles < 180°;
    they approach 180° as the free arcs vanish: 170° at 2.8 rad), the disc's and the cradle's
    contact ends bit for bit the same points (so the mortar coverage is exact at the ends)."""
    levels = (0, 1) if angle >= 0.5 else (0,)  # small angles: the disc's cells follow the arc
    Cl, Cr = contact_ends(CENTER, R, angle)
    for level in levels:
        d, c = half_disc(angle=angle, level=level), cradle(angle=angle, level=level)
        for m in (d, c):
            assert (cell_areas(m) > 0).all() and max_angle_deg(m) < 179.0
        Pd = d.points[trace(d, "contact").nodes]
        Pc = c.points[trace(c, "contact").nodes]
        np.testing.assert_array_equal(Pd[[0, -1]], [Cl, Cr])
        np.testing.assert_array_equal(Pc[[0, -1]], [Cr, Cl])


def test_contact_normals_point_away_from_each_body():
    d, c = half_disc(level=1), cradle(level=1)
    td, tc = trace(d, "contact"), trace(c, "contact")
    radial_d = (d.points[td.nodes] - CENTER) / R  # (k, 2) unit, away from the disc centre
    radial_c = (c.points[tc.nodes] - CENTER) / R
    assert (np.sum(td.normals * radial_d, 1) > 0.99).all()  # disc: outward, down
    assert (np.sum(tc.normals * radial_c, 1) < -0.99).all()  # cradle: up, towards the centre
    assert (td.normals[:, 1] < 0).all() and (tc.normals[:, 1] > 0).all()


def test_parts_and_non_matching_defaults():
    d, c = half_disc(), cradle()
    assert set(d.boundaries) == {"top", "contact", "free_left", "free_right"}
    assert set(c.boundaries) == {"bottom", "right", "contact", "left"}
    top = trace(d, "top")
    np.testing.assert_allclose(d.points[top.nodes, 1], 1.5)
    np.testing.assert_allclose(d.points[top.nodes[[0, -1]], 0], [1.0, -1.0])  # right to left
    closed_d = trace(d, ["top", "free_left", "contact", "free_right"])
    closed_c = trace(c, ["bottom", "right", "contact", "left"])
    for t in (closed_d, closed_c):
        assert t.facets.shape[0] == t.nodes.size  # each body's boundary is one closed loop
    bottom = trace(c, "bottom")
    np.testing.assert_allclose(c.points[bottom.nodes], np.c_[np.linspace(-1, 1, 13), np.zeros(13)])


def test_element_sizes_are_roughly_uniform():
    for m in (half_disc(level=2), cradle(level=2)):
        P = m.points[m.cells]
        edges = np.linalg.norm(np.roll(P, -1, 1) - P, axis=-1)  # (n_cells, 4)
        assert edges.max() / edges.min() < 4.0


def test_bad_angle_is_rejected():
    with pytest.raises(ValueError, match="angle"):
        half_disc(angle=np.pi)
    with pytest.raises(ValueError, match="angle"):
        cradle(angle=0.0)
