"""Tests of fem.mapped: Coons blocks, curves, gluing."""

import numpy as np
import pytest

from fem.facets import trace
from fem.mapped import arc, coons_block, glue, reparametrise, segment

ALL = {"bottom": "bottom", "right": "right", "top": "top", "left": "left"}


def square(x0=0.0, y0=0.0, a=1.0, n=4, names=ALL):
    c00, c10, c11, c01 = (x0, y0), (x0 + a, y0), (x0 + a, y0 + a), (x0, y0 + a)
    return coons_block(
        segment(c00, c10), segment(c10, c11), segment(c11, c01), segment(c01, c00), n, n, names
    )


def cell_areas(m):
    P = m.points[m.cells]  # (n_cells, 4, 2)
    x, y = P[..., 0], P[..., 1]
    return 0.5 * (x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y).sum(1)


def annulus_sector(n, r0=1.0, r1=2.0):
    """The quarter annulus r0 < |x| < r1, 0 < θ < π/2, as one block."""
    return coons_block(
        segment((r0, 0), (r1, 0)),
        arc((0, 0), r1, 0, np.pi / 2),
        segment((0, r1), (0, r0)),
        arc((0, 0), r0, np.pi / 2, 0),
        n,
        2 * n,
        {"right": "outer", "left": "inner", "bottom": "bottom", "top": "top"},
    )


def test_unit_square_is_the_tensor_grid():
    m = square(n=3)
    x = np.linspace(0, 1, 4)
    X, Y = np.meshgrid(x, x)
    np.testing.assert_allclose(m.points, np.stack([X.ravel(), Y.ravel()], 1), atol=1e-15)
    np.testing.assert_allclose(cell_areas(m), 1 / 9, rtol=1e-13)
    assert m.cell_type == "quad" and m.n_cells == 9


@pytest.mark.parametrize(
    "name, normal", [("bottom", (0, -1)), ("right", (1, 0)), ("top", (0, 1)), ("left", (-1, 0))]
)
def test_sides_have_outward_normals_and_are_ordered(name, normal):
    m = square(n=5)
    t = trace(m, name)
    np.testing.assert_allclose(t.normals, np.broadcast_to(normal, t.normals.shape), atol=1e-14)
    assert t.nodes.size == 6 and np.isclose(t.measures.sum(), 1.0)


def test_sides_with_one_name_form_one_counterclockwise_loop():
    m = square(n=3, names={"bottom": "b", "right": "o", "top": "o", "left": "o"})
    assert set(m.boundaries) == {"b", "o"}
    t = trace(m, "o")  # one chain: right, then top, then left
    np.testing.assert_allclose(m.points[t.nodes[[0, -1]]], [[1, 0], [0, 0]])
    loop = trace(m, ["b", "o"])  # closed loop
    assert loop.facets.shape[0] == loop.nodes.size == 12
    P = m.points[loop.nodes]
    shoelace = 0.5 * np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1])
    assert np.isclose(shoelace, 1.0)  # counterclockwise


def test_arc_nodes_lie_on_the_circle_and_area_converges():
    errs, hs = [], []
    for n in (4, 8, 16, 32):
        m = annulus_sector(n)
        for name, r in (("outer", 2.0), ("inner", 1.0)):
            nodes = m.boundary_nodes(name)
            np.testing.assert_allclose(np.linalg.norm(m.points[nodes], axis=1), r, rtol=1e-15)
        assert (cell_areas(m) > 0).all()
        errs.append(abs(cell_areas(m).sum() - 3 * np.pi / 4))
        hs.append(m.h)
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 1.9 < rate < 2.1, rate
    m = annulus_sector(8)
    t = trace(m, "outer")
    radial = m.points[t.nodes] / 2.0
    assert (np.sum(t.normals * radial, axis=1) > 0.99).all()  # outward = away from the centre
    t = trace(m, "inner")
    radial = m.points[t.nodes]
    assert (np.sum(t.normals * radial, axis=1) < -0.99).all()  # outward = towards the centre


def test_reparametrised_side_puts_nodes_at_the_knots():
    knots = [0.0, 0.1, 0.5, 0.55, 1.0]
    m = coons_block(
        reparametrise(segment((0, 0), (2, 0)), knots),
        segment((2, 0), (2, 1)),
        segment((2, 1), (0, 1)),
        segment((0, 1), (0, 0)),
        4,
        2,
        {"bottom": "b"},
    )
    np.testing.assert_allclose(m.points[trace(m, "b").nodes, 0], 2 * np.array(knots))
    with pytest.raises(ValueError, match="increase"):
        reparametrise(segment((0, 0), (1, 0)), [0.0, 0.6, 0.5, 1.0])


def test_clockwise_block_is_rejected():
    c00, c01, c11, c10 = (0, 0), (0, 1), (1, 1), (1, 0)
    with pytest.raises(ValueError, match="inverted or degenerate"):
        coons_block(
            segment(c00, c01), segment(c01, c11), segment(c11, c10), segment(c10, c00), 2, 2, {}
        )


def test_degenerate_block_is_rejected():
    """A triangle given as a quad (one side collapsed to a point) has degenerate cells."""
    p = (0.5, 1.0)
    with pytest.raises(ValueError, match="inverted or degenerate"):
        coons_block(
            segment((0, 0), (1, 0)), segment((1, 0), p), segment(p, p), segment(p, (0, 0)), 2, 2, {}
        )


def test_sides_that_do_not_meet_are_rejected():
    with pytest.raises(ValueError, match="do not meet"):
        coons_block(
            segment((0, 0), (1, 0)),
            segment((1, 0), (1, 1)),
            segment((1, 1), (0, 1)),
            segment((0, 1), (0, 0.1)),
            2,
            2,
            {},
        )
    with pytest.raises(ValueError, match="unknown side"):
        square(names={"north": "x"})


def test_glue_merges_nodes_parts_and_drops_interior_edges():
    n = 4
    a = square(
        0.0, 0.0, n=n, names={"bottom": "outer", "right": "iface", "top": "outer", "left": "outer"}
    )
    b = square(
        1.0, 0.0, n=n, names={"bottom": "outer", "right": "outer", "top": "outer", "left": "iface"}
    )
    m = glue([a, b])
    assert m.n_nodes == 2 * (n + 1) ** 2 - (n + 1)
    assert m.n_cells == 2 * n * n
    assert "iface" not in m.boundaries  # the shared side became interior
    t = trace(m, "outer")  # a single closed counterclockwise loop
    assert t.facets.shape[0] == t.nodes.size == 6 * n
    assert np.isclose(t.measures.sum(), 6.0)
    P = m.points[t.nodes]
    assert np.isclose(
        0.5 * np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1]), 2.0
    )
    np.testing.assert_allclose(cell_areas(m), 1 / n**2, rtol=1e-13)
    # every interior edge is shared by exactly two cells, every loop edge by one
    e = np.sort(np.stack([m.cells, np.roll(m.cells, -1, 1)], -1).reshape(-1, 2), 1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert (counts <= 2).all() and (counts == 1).sum() == 6 * n


def test_glue_keeps_separate_blocks_apart():
    m = glue([square(0.0, 0.0, n=2), square(1.5, 0.0, n=2)])
    assert m.n_nodes == 18 and m.boundaries["bottom"].shape == (4, 2)
