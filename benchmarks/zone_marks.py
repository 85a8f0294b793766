"""Candidate contact-zone markings for the adaptive loop (issue 32, Hertz third pass), each a
`problems.pipeline.adaptive.ZoneMarks`: (model, solution, meshes, the Dörfler marks of the
energy estimate) → {slave body: (n_cells,) bool, those marks and more}, for
`adapt(..., contact_zone=MARKS[name])`:

- "touching": every cell with a vertex at a touching node (`adaptive.touching_cells`, what
  `mixvi solve --accuracy X --contact-zone` does);
- "edge": only the cells at the zone's edge: the nodes of each segment whose ends differ in
  touch (the last touching and the first open node) and their neighbours along the surface;
- "touching_edge": "touching" and "edge" (the first open nodes' cells too);
- "edge_peak": "edge" plus the node of the largest λ_n and its neighbours (the peak pressure);
- "jump", "rough": a multiplier indicator on its own Dörfler set (θ = 0.5), added to the
  energy's: per surface node k between segments of lengths h_l, h_r (h = (h_l + h_r)/2),
  η_k² = h² |[λ_h]_k|² / c_u with the jump of the dual multiplier λ_h = Σ λ_j ψ̃_j at node k
  ("jump"), or η_k² = h² r_k² / c_u with the roughness r_k = λ_n,k − (h_r λ_n,k−1 +
  h_l λ_n,k+1)/(h_l + h_r) (the nodal pressure against its neighbours' line, "rough"),
  split half and half between the two segments' cells;
- "surface_red": the cells on touching segments are split only red (`surface_red`);
  "fan_red": the same for every cell at a touching node;
- NAME + "_graded", and "graded" (Dörfler's marks alone): NAME's marks closed so that
  neighbouring contact segments of the slave differ by at most a factor 2 after refinement
  (`graded_chain`, predicted from the marked cells' contact segments; the bisections of
  the conformity closure are not predicted).

`MARKS` maps the names to the functions (`bench_adaptive.py --zone NAME`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fem.marking import TIE, dorfler_mark
from problems.pipeline.adaptive import touching_cells


def _touch(model: Any, sol: Any) -> np.ndarray:
    """(k,) bool over the slave trace's nodes: touching."""
    c = model.contact
    touch = np.zeros(c.tr.nodes.size, dtype=bool)
    touch[c.rows_n[model.contact_state(sol)["touch"]]] = True
    return touch


def _ring(sel: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """sel (k,) bool over trace nodes with their neighbours along the segments seg (n, 2)."""
    out = sel.copy()
    out[seg[sel[seg[:, 0]], 1]] = True
    out[seg[sel[seg[:, 1]], 0]] = True
    return out


def _cells_at(mesh: Any, nodes: np.ndarray) -> np.ndarray:
    """(n_cells,) bool: cells with a vertex among the global nodes."""
    return np.isin(mesh.cells, nodes).any(axis=1)


def facet_cells(mesh: Any, facets: np.ndarray) -> np.ndarray:
    """(n_f,) the cell of each boundary edge facets (n_f, 2) of a triangle mesh."""
    n, T = mesh.n_nodes, mesh.cells  # T (n_cells, 3)
    e = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])  # (3 n_cells, 2)
    codes = np.minimum(e[:, 0], e[:, 1]).astype(np.int64) * n + e.max(axis=1)
    cell = np.tile(np.arange(T.shape[0]), 3)
    order = np.argsort(codes, kind="stable")
    key = np.minimum(facets[:, 0], facets[:, 1]).astype(np.int64) * n + facets.max(axis=1)
    return cell[order][np.searchsorted(codes[order], key)]


def edge(
    model: Any, sol: Any, meshes: dict, marked: dict, peak: bool = False
) -> dict[str, np.ndarray]:
    """ "edge" (and with `peak` "edge_peak") of the module docstring."""
    c = model.contact
    seg = c.tr.facets  # (n_seg, 2) trace indices
    touch = _touch(model, sol)
    change = np.zeros_like(touch)
    change[seg[touch[seg[:, 0]] != touch[seg[:, 1]]].ravel()] = True
    sel = _ring(change, seg)
    if peak:
        top = np.zeros_like(touch)
        top[c.rows_n[np.argmax(c.normal(sol.lam))]] = True
        sel |= _ring(top, seg)
    return {c.slave.name: marked[c.slave.name] | _cells_at(meshes[c.slave.name], c.tr.nodes[sel])}


def _chain(tr: Any) -> np.ndarray:
    """(m,) segments e whose end is the start of segment e + 1 (their common node)."""
    return np.flatnonzero(tr.facets[:-1, 1] == tr.facets[1:, 0])


def _c_u(model: Any) -> float:
    return float(np.linalg.eigvalsh(model.contact.slave.material.C)[-1])


def multiplier_indicator(model: Any, sol: Any, meshes: dict, kind: str) -> np.ndarray:
    """(n_cells,) η² of the slave's cells, "jump" or "rough" of the module docstring."""
    from problems.plugins.contact.error_estimate import _multiplier_at

    c = model.contact
    tr = c.tr
    nxt = _chain(tr)  # (m,) node tr.facets[nxt, 1] between segments nxt and nxt + 1
    h = 0.5 * (tr.measures[nxt] + tr.measures[nxt + 1])  # (m,)
    if kind == "jump":
        seg = np.arange(tr.facets.shape[0])
        end = _multiplier_at(c, sol.lam, seg, np.ones(seg.size))[0]  # (n_seg, 2) at t = 1
        start = _multiplier_at(c, sol.lam, seg, np.zeros(seg.size))[0]  # (n_seg, 2) at t = 0
        r = np.linalg.norm(end[nxt] - start[nxt + 1], axis=1)  # (m,)
    else:
        lam = np.zeros(tr.nodes.size)
        lam[c.rows_n] = c.normal(sol.lam)
        a, k, b = tr.facets[nxt, 0], tr.facets[nxt, 1], tr.facets[nxt + 1, 1]  # (m,) each
        hl, hr = tr.measures[nxt], tr.measures[nxt + 1]
        r = lam[k] - (hr * lam[a] + hl * lam[b]) / (hl + hr)
    val = h**2 * r**2 / _c_u(model)  # (m,)
    cells = facet_cells(meshes[c.slave.name], tr.nodes[tr.facets])  # (n_seg,)
    out = np.zeros(meshes[c.slave.name].n_cells)
    np.add.at(out, cells[nxt], 0.5 * val)
    np.add.at(out, cells[nxt + 1], 0.5 * val)
    return out


def multiplier(model: Any, sol: Any, meshes: dict, marked: dict, kind: str) -> dict:
    """ "jump" or "rough": the Dörfler set (θ = 0.5) of `multiplier_indicator`, added."""
    eta2 = multiplier_indicator(model, sol, meshes, kind)
    name = model.contact.slave.name
    return {name: marked[name] | dorfler_mark(np.sqrt(eta2), 0.5)}


def surface_red(
    model: Any, sol: Any, meshes: dict, marked: dict, fans: bool = False
) -> dict[str, np.ndarray]:
    """ "surface_red": every slave cell on a contact segment with a touching end that the
    refinement would split at all (a marked edge after the conformity closure of
    `fem.bisection`) is marked, i.e. split red into four similar triangles instead of by
    bisections, until none is left to split otherwise."""
    from fem.bisection import _closure, _edge_cells, _edges

    c = model.contact
    mesh = meshes[c.slave.name]
    touch = _touch(model, sol)
    if fans:  # (n_cells,) cells at a touching node
        zone = _cells_at(mesh, c.tr.nodes[touch])
    else:  # (n_cells,) cells on a touching segment
        zone = np.zeros(mesh.n_cells, dtype=bool)
        zone[facet_cells(mesh, c.tr.nodes[c.tr.facets[touch[c.tr.facets].any(axis=1)]])] = True
    codes, cell_edges = _edges(mesh.cells, mesh.n_nodes)  # (n_edges,), (n_cells, 3)
    edge_cells = _edge_cells(cell_edges, codes.size)
    m = marked[c.slave.name].copy()
    while True:
        edges = np.zeros(codes.size, dtype=bool)
        edges[cell_edges[m].ravel()] = True
        split = _closure(cell_edges, edge_cells, edges)[cell_edges].any(axis=1)  # (n_cells,)
        add = split & zone & ~m
        if not add.any():
            return {c.slave.name: m}
        m |= add


def graded_chain(
    h: np.ndarray, halved: np.ndarray, pairs: np.ndarray, ratio: float = 2.0
) -> np.ndarray:
    """`halved` (n,) extended until neighbouring segments' sizes after refinement (h/2 where
    halved) differ by at most `ratio` (to TIE): the larger of a pair that breaks it is halved,
    until none does. h (n,) sizes, pairs (m, 2) neighbouring segments."""
    out = np.array(halved, dtype=bool)
    i, j = np.asarray(pairs).reshape(-1, 2).T  # (m,) each
    while True:
        s = np.where(out, 0.5 * h, h)  # (n,)
        big = np.where(s[i] > s[j], i, j)  # (m,)
        bad = np.maximum(s[i], s[j]) > ratio * np.minimum(s[i], s[j]) * (1.0 + TIE)
        add = big[bad & ~out[big]]
        if add.size == 0:
            return out
        out[add] = True


def graded(marks):
    """The marking `marks` followed by the grading closure along the slave's contact
    segments (`graded_chain`)."""

    def closed(model: Any, sol: Any, meshes: dict, marked: dict) -> dict[str, np.ndarray]:
        out = marks(model, sol, meshes, marked)
        c = model.contact
        tr = c.tr
        m = out.get(c.slave.name, marked[c.slave.name])
        cells = facet_cells(meshes[c.slave.name], tr.nodes[tr.facets])  # (n_seg,)
        nxt = _chain(tr)
        halved = graded_chain(tr.measures, m[cells], np.stack([nxt, nxt + 1], axis=1))
        m = m.copy()
        m[cells[halved]] = True
        return {**out, c.slave.name: m}

    return closed


MARKS = {
    "touching": touching_cells,
    "edge": edge,
    "edge_peak": lambda *a: edge(*a, peak=True),
    "jump": lambda *a: multiplier(*a, "jump"),
    "rough": lambda *a: multiplier(*a, "rough"),
    "touching_edge": lambda m, s, ms, mk: edge(m, s, ms, touching_cells(m, s, ms, mk)),
    "surface_red": surface_red,
    "fan_red": lambda *a: surface_red(*a, fans=True),
}
MARKS.update({f"{k}_graded": graded(v) for k, v in list(MARKS.items())})
MARKS["graded"] = graded(lambda model, sol, meshes, marked: {})
