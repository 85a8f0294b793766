"""Candidate contact-zone markings for the adaptive loop on Hertz (docs/benchmarks.md, "Hertz
against uniform refinement"), each a `problems.pipeline.adaptive.ZoneMarks`: (model, solution,
meshes, the Dörfler marks of the energy estimate) → {slave body: (n_cells,) bool, those marks
and more}, for `adapt(..., contact_zone=MARKS[name])`:

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
- "peak_red" red fans only at the node of the largest λ_n and its neighbours (the support of
  the peak pressure's dual function); "core_red", "core50_red" red fans at the touching nodes with
  λ_n ≥ 0.8, 0.5 × its maximum;
  "contact_w10", "contact_w100" the Dörfler set (θ = 0.5) of the estimate with its contact
  terms' share of η_T² scaled by 10 or 100, added (`contact_weighted`); "near_zone",
  "near_zone50", "near_zone25" every cell within 1, 0.5, 0.25 × the zone's half-length of a
  touching node, plus "fan_red" (`near_zone`); "zone_weighted", "zone_weighted1",
  "zone_weighted_t7" the Dörfler set of η_T min(1, ℓ/d_T)^p (p = 2, 1; θ = 0.5, 0.7) added,
  plus "fan_red" (`zone_weighted`: a goal-oriented weight, the decay of a contact-load
  functional's dual solution away from the zone); "near_level", "near_level4" a minimum
  level: cells within ℓ of a touching node coarser than 2×, 4× the longest touching segment,
  plus "fan_red" (`near_level`); "dual" the goal-oriented (dual-weighted residual) marks:
  per goal (the peak pressure p0, the half-width's second moment a) the Dörfler set of
  η_T(u_h) η_T(z_h) with z_h the discrete dual solution (`dual_solution`,
  `dual_indicators`, `dual_weighted`), added; "dual_red" and "dual_a_red" (a only) plus
  "fan_red", "dual_red_t8" with θ = 0.8 on the goal sets, "dual_union" / "dual_union_red"
  the Dörfler sets of η_T(z_h) itself, "dual_peak_red" plus "peak_red";
- "layers3" the cells within 3 vertex rings of the touching nodes split only red (`red_layers`:
  "fan_red" is 0 rings), so the zone's surface layer is regular a few cells deep and its nodal
  multiplier has no odd-even oscillation; "near_box" the near field as a box graded from the
  zone's surface, plus "layers3" (`near_box`); "near_box_f2r2" its size target 2√2 × the
  zone's median segment instead of 2× (a cycle's near field √2 coarser: the step between two
  near_box cycles); "near_box_tight" a narrower box (width 1.1 ℓ), full size only to 0.8 ℓ
  deep, 2.5× the median segment (tuned on the shipped Hertz load, where it meets the target:
  uniform level 5's error with 5× fewer unknowns; frozen, it meets it on one of four other
  loads: docs/benchmarks.md, "Held out");
  "near_box_paced" the target falling by at most √2 per cycle (`NearBoxPaced`);
  "near_box_nvb" its box cells bisected once (h ÷ √2) instead of split into 4, the rings
  still red (`near_box_nvb`); "size_graded" no box: every cell graded by its distance to
  the zone's surface (`size_graded`, `zone_distance`); "box_dorfler30",
  "box_dorfler60" a second Dörfler set (θ = 0.3, 0.6) of the estimate restricted to
  near_box's box (`box_dorfler`);
- "dwr" goal-oriented marks with the weights z − I_h z of the dual solution z on the once
  uniformly refined mesh (`goal_marks.dwr`): per goal (p0, a) the Dörfler set (θ = 0.5) of
  the fine residual of (u_h, λ_h) weighted by z − I_h z, added to the energy's, then
  "layers3"; "dwr_goal" the same without the energy's marks; "dwr_goal_pu" dwr_goal with
  the indicators summed per vertex patch (signs cancelling) before their size is taken;
- NAME + "_graded", and "graded" (Dörfler's marks alone): NAME's marks closed so that
  neighbouring contact segments of the slave differ by at most a factor 2 after refinement
  (`graded_chain`, predicted from the marked cells' contact segments; the bisections of
  the conformity closure are not predicted).

`MARKS` maps the names to the functions (`bench_adaptive.py --zone NAME`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from benchmarks.goal_marks import dwr
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


def red_split(
    model: Any, meshes: dict, marked: dict, zone: np.ndarray, bisect: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """The slave's marks with every cell of `zone` (n_cells,) bool that the refinement would
    split at all (a marked edge after the conformity closure of `fem.bisection`, with the
    refinement edges of the `bisect` cells (n_cells,) bool marked too) marked, i.e. split red
    into four similar triangles instead of by bisections, until none is left to split
    otherwise."""
    from fem.bisection import _closure, _edge_cells, _edges

    c = model.contact
    mesh = meshes[c.slave.name]
    codes, cell_edges = _edges(mesh.cells, mesh.n_nodes)  # (n_edges,), (n_cells, 3)
    edge_cells = _edge_cells(cell_edges, codes.size)
    m = marked[c.slave.name].copy()
    while True:
        edges = np.zeros(codes.size, dtype=bool)
        edges[cell_edges[m].ravel()] = True
        if bisect is not None:
            edges[cell_edges[bisect, 0]] = True
        split = _closure(cell_edges, edge_cells, edges)[cell_edges].any(axis=1)  # (n_cells,)
        add = split & zone & ~m
        if not add.any():
            return {c.slave.name: m}
        m |= add


def red_fans(model: Any, meshes: dict, marked: dict, sel: np.ndarray) -> dict[str, np.ndarray]:
    """`red_split` of the cells at the trace nodes of `sel` (k,) bool (their fans)."""
    c = model.contact
    return red_split(model, meshes, marked, _cells_at(meshes[c.slave.name], c.tr.nodes[sel]))


def peak_red(model: Any, sol: Any, meshes: dict, marked: dict, rings: int = 1) -> dict:
    """ "peak_red": red fans (`red_fans`) only at the node of the largest λ_n and its
    `rings` neighbours on each side along the surface."""
    c = model.contact
    sel = np.zeros(c.tr.nodes.size, dtype=bool)
    sel[c.rows_n[np.argmax(c.normal(sol.lam))]] = True
    for _ in range(rings):
        sel = _ring(sel, c.tr.facets)
    return red_fans(model, meshes, marked, sel)


def core_red(model: Any, sol: Any, meshes: dict, marked: dict, fraction: float = 0.8) -> dict:
    """ "core_red": red fans (`red_fans`) at the touching nodes whose λ_n is at least
    `fraction` of the largest (the zone's core, away from its edge)."""
    c = model.contact
    lam = c.normal(sol.lam)  # (n_rows,)
    sel = np.zeros(c.tr.nodes.size, dtype=bool)
    sel[c.rows_n[lam >= fraction * lam.max()]] = True
    return red_fans(model, meshes, marked, sel & _touch(model, sol))


def near_zone(
    model: Any, sol: Any, meshes: dict, marked: dict, radius: float = 1.0, red: bool = True
) -> dict:
    """ "near_zone": every slave cell with a vertex within `radius` × the zone's half-length
    (half the largest distance between touching nodes) of a touching node, marked; with
    `red` then the touching nodes' fans red (`red_fans`)."""
    from scipy.spatial import cKDTree

    c = model.contact
    mesh = meshes[c.slave.name]
    touch = _touch(model, sol)
    p = mesh.points[c.tr.nodes[touch]]  # (n_touch, 2)
    half = 0.5 * float(np.max(np.linalg.norm(p[:, None] - p[None], axis=-1)))
    d = cKDTree(p).query(mesh.points)[0]  # (n_nodes,) distance to the nearest touching node
    near = (d[mesh.cells] < radius * half).any(axis=1)  # (n_cells,)
    out = {c.slave.name: marked[c.slave.name] | near}
    return red_fans(model, meshes, out, touch) if red else out


def _slave_eta(model: Any, sol: Any, drop: str | None = None) -> np.ndarray:
    """(n_cells,) η_T of the slave body (`error_estimate.indicators`, with `drop`), for a
    2D contact or a signorini model."""
    from problems.plugins import signorini
    from problems.plugins.contact import error_estimate as ce
    from problems.plugins.contact import plane as pc

    if "bodies" in model.scene.data:  # a contact scene
        spec = pc.SCENE_MODEL
    else:

        def spec(scene):
            return signorini.piezo_spec(scene.validated(signorini.SCENE_MODEL))

    return ce.indicators(spec, model, sol, drop=drop)[model.contact.slave.name]


def zone_weighted(
    model: Any, sol: Any, meshes: dict, marked: dict, theta: float = 0.5, power: float = 2.0
) -> dict:
    """ "zone_weighted": the Dörfler set (θ) of η_T w_T, w_T = min(1, ℓ / d_T)^power with ℓ the
    zone's half-length and d_T the distance of T's centroid to the nearest touching node (the
    decay of a contact-load functional's dual solution away from the zone), added to the
    marks, then the touching nodes' fans red (`red_fans`)."""
    from scipy.spatial import cKDTree

    c = model.contact
    mesh = meshes[c.slave.name]
    eta = _slave_eta(model, sol)  # (n_cells,)
    touch = _touch(model, sol)
    p = mesh.points[c.tr.nodes[touch]]  # (n_touch, 2)
    half = 0.5 * float(np.max(np.linalg.norm(p[:, None] - p[None], axis=-1)))
    d = cKDTree(p).query(mesh.points[mesh.cells].mean(axis=1))[0]  # (n_cells,)
    w = np.minimum(1.0, half / np.maximum(d, 1e-300)) ** power  # (n_cells,)
    out = {c.slave.name: marked[c.slave.name] | dorfler_mark(eta * w, theta)}
    return red_fans(model, meshes, out, touch)


def dual_solution(model: Any, sol: Any, goal: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The discrete dual solution of a goal functional of the normal multiplier, linearised
    at the solution's touching set R (frictionless: the tangential rows carry no
    constraint): [A B_Rᵀ; B_R 0] [z; μ] = [0; j], j = ∂J/∂λ_R (Becker and Rannacher's
    dual-weighted residual; for contact, Blum, Schröder and Suttmeier; Rademacher). goal
    "p0": J = λ_n at the touching node nearest x = 0; "a": J = Σ w_k λ_k x_k² / Σ w_k λ_k
    (the Hertz half-width's second moment), j_k = w_k (x_k² − J) / J. Returns z (n,) over
    the unknowns, μ (m,) over the rows of B (zero off R) and j (m,) likewise. Then
    j·λ_h = f·z + gap·μ (A symmetric, B_R u_h = gap_R)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    c = model.contact
    touch = model.contact_state(sol)["touch"]  # (N_n,)
    rows = c.idx_n[touch]  # (n_R,) rows of B
    x = c.slave.mesh.points[c.tr.nodes[c.rows_n], 0][touch]  # (n_R,)
    j = np.zeros(rows.size)
    if goal == "p0":
        j[np.argmin(np.abs(x))] = 1.0
    else:
        w = c.W_n[c.rows_n][touch]  # (n_R,)
        lam = c.normal(sol.lam)[touch]
        J = float((w * lam * x**2).sum() / (w * lam).sum())
        j = w * (x**2 - J) / J
    A, B = model.vi.A, model.vi.B[rows]  # (n, n), (n_R, n)
    K = sp.bmat([[A, B.T], [B, None]], format="csc")
    zm = spla.spsolve(K, np.concatenate([np.zeros(A.shape[0]), j]))  # (n + n_R,)
    mu, jm = np.zeros(model.vi.B.shape[0]), np.zeros(model.vi.B.shape[0])
    mu[rows], jm[rows] = zm[A.shape[0] :], j
    return zm[: A.shape[0]], mu, jm


def dual_indicators(model: Any, sol: Any, goal: str) -> np.ndarray:
    """(n_cells,) the residual indicators η_T(z_h) of the slave body for the dual solution
    z_h of `dual_solution`: the primal's estimator with zero Dirichlet values and without
    the normal defect (z_h's constraint data is j, not the gap)."""
    import dataclasses
    from types import SimpleNamespace

    z, mu, _ = dual_solution(model, sol, goal)
    dual = dataclasses.replace(model, values=np.zeros_like(model.values))
    return _slave_eta(dual, SimpleNamespace(u=z, lam=mu), drop="normal")


def dual_weighted(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    goals: tuple[str, ...] = ("p0", "a"),
    theta: float = 0.5,
    red: bool = True,
    union: bool = False,
) -> dict:
    """ "dual_weighted": per goal of `dual_indicators` the Dörfler set (θ) of the product
    η_T(u_h) η_T(z_h) (goal-oriented marking: Mommer and Stevenson; Feischl, Praetorius and
    van der Zee), all added to the marks; with `red` then the touching nodes' fans red
    (`red_fans`)."""
    c = model.contact
    eta = _slave_eta(model, sol)  # (n_cells,)
    m = marked[c.slave.name].copy()
    for goal in goals:
        zeta = dual_indicators(model, sol, goal)  # (n_cells,)
        m |= dorfler_mark(zeta if union else eta * zeta, theta)
    out = {c.slave.name: m}
    return red_fans(model, meshes, out, _touch(model, sol)) if red else out


def near_level(
    model: Any, sol: Any, meshes: dict, marked: dict, factor: float = 2.0, radius: float = 1.0
) -> dict:
    """ "near_level": a minimum level around the zone: every slave cell whose centroid lies
    within `radius` × the zone's half-length ℓ of a touching node and whose longest edge is
    more than `factor` × the longest touching contact segment is marked (the near field
    kept as fine as the zone's surface, as the box of `bench_adaptive.hertz_limit`), then
    the touching nodes' fans red (`red_fans`)."""
    from scipy.spatial import cKDTree

    c = model.contact
    mesh = meshes[c.slave.name]
    touch = _touch(model, sol)
    p = mesh.points[c.tr.nodes[touch]]  # (n_touch, 2)
    half = 0.5 * float(np.max(np.linalg.norm(p[:, None] - p[None], axis=-1)))
    h_zone = float(c.tr.measures[touch[c.tr.facets].all(axis=1)].max())
    P = mesh.points[mesh.cells]  # (n_cells, 3, 2)
    h = longest_edges(P)  # (n_cells,)
    d = cKDTree(p).query(P.mean(axis=1))[0]  # (n_cells,)
    out = {c.slave.name: marked[c.slave.name] | ((d < radius * half) & (h > factor * h_zone))}
    return red_fans(model, meshes, out, touch)


def contact_weighted(
    model: Any, sol: Any, meshes: dict, marked: dict, weight: float = 10.0, theta: float = 0.5
) -> dict:
    """ "contact_w10": the Dörfler set (θ) of the estimate with its contact terms' share of η_T²
    scaled by `weight`, added to the marks."""
    from problems.plugins.contact import error_estimate as ce

    name = model.contact.slave.name
    e2 = _slave_eta(model, sol) ** 2  # (n_cells,)
    share = sum(e2 - _slave_eta(model, sol, drop=t) ** 2 for t in ce.TERMS)  # contact terms
    w2 = e2 + (weight - 1.0) * share
    return {name: marked[name] | dorfler_mark(np.sqrt(np.maximum(w2, 0.0)), theta)}


def surface_red(
    model: Any, sol: Any, meshes: dict, marked: dict, fans: bool = False
) -> dict[str, np.ndarray]:
    """ "surface_red": the slave cells on a contact segment with a touching end split only red
    (`red_split`); with `fans` ("fan_red") every cell at a touching node."""
    c = model.contact
    touch = _touch(model, sol)
    if fans:
        return red_fans(model, meshes, marked, touch)
    zone = np.zeros(meshes[c.slave.name].n_cells, dtype=bool)  # cells on a touching segment
    zone[facet_cells(meshes[c.slave.name], c.tr.nodes[c.tr.facets[touch[c.tr.facets].any(1)]])] = (
        True
    )
    return red_split(model, meshes, marked, zone)


def red_layers(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    rings: int = 3,
    bisect: np.ndarray | None = None,
) -> dict:
    """ "layers3": `red_split` of the slave cells with a vertex within `rings` vertex rings of
    a touching node (0 rings: the touching nodes' fans, "fan_red"), with `bisect` as there."""
    c = model.contact
    mesh = meshes[c.slave.name]
    near = np.zeros(mesh.n_nodes, dtype=bool)  # (n_nodes,)
    near[c.tr.nodes[_touch(model, sol)]] = True
    for _ in range(rings):
        near[mesh.cells[near[mesh.cells].any(axis=1)].ravel()] = True
    return red_split(model, meshes, marked, near[mesh.cells].any(axis=1), bisect)


def longest_edges(P: np.ndarray) -> np.ndarray:
    """(n_cells,) each triangle's longest edge, P (n_cells, 3, 2) its corners."""
    return np.linalg.norm(P - np.roll(P, 1, axis=1), axis=-1).max(axis=1)


def _zone_frame(model: Any, sol: Any, mesh: Any) -> tuple[float, float, float, float]:
    """(ℓ, x_c, y_top, h_zone): the zone's half-length (half the x-extent of the touching
    nodes), its centre, its highest touching node's y and its median touching segment."""
    c = model.contact
    touch = _touch(model, sol)  # (k,)
    p = mesh.points[c.tr.nodes[touch]]  # (n_touch, 2)
    half, xc = 0.5 * np.ptp(p[:, 0]), 0.5 * (p[:, 0].max() + p[:, 0].min())
    h_zone = float(np.median(c.tr.measures[touch[c.tr.facets].all(axis=1)]))
    return float(half), float(xc), float(p[:, 1].max()), h_zone


def box_coarse(
    mesh: Any,
    frame: tuple[float, float, float, float],
    size: float,
    width: float = 1.3,
    depth: float = 2.6,
    full: float = 1.3,
    step: float = 0.5,
) -> np.ndarray:
    """(n_cells,) bool: the cells whose centroid lies in the box |x − x_c| < width ℓ, at a
    depth t = (y_top − y) / ℓ < `depth` (frame = (ℓ, x_c, y_top, ·) of `_zone_frame`), and
    whose longest edge exceeds size × 2^max(0, (t − full) / step): as fine as `size` to the
    depth `full` ℓ, then twice coarser every `step` ℓ."""
    half, xc, y_top, _ = frame
    P = mesh.points[mesh.cells]  # (n_cells, 3, 2)
    h = longest_edges(P)  # (n_cells,)
    centroid = P.mean(axis=1)  # (n_cells, 2)
    t = (y_top - centroid[:, 1]) / half  # (n_cells,) depth in zone half-lengths
    inside = (np.abs(centroid[:, 0] - xc) < width * half) & (t < depth)
    return inside & (h > size * 2.0 ** np.maximum(0.0, (t - full) / step))


def near_box(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    width: float = 1.3,
    depth: float = 2.6,
    full: float = 1.3,
    step: float = 0.5,
    factor: float = 2.0,
) -> dict:
    """ "near_box": the slave cells of `box_coarse` with size `factor` × the zone's median
    segment, added to the marks: the near field kept as fine as the zone's surface to the
    depth `full` ℓ, then twice coarser every `step` ℓ (as the nested a priori boxes of
    `bench_adaptive.box_mesh`); then `red_layers` (3 rings)."""
    c = model.contact
    mesh = meshes[c.slave.name]
    frame = _zone_frame(model, sol, mesh)
    coarse = box_coarse(mesh, frame, factor * frame[3], width, depth, full, step)
    out = {c.slave.name: marked[c.slave.name] | coarse}
    return red_layers(model, sol, meshes, out)


def near_box_nvb(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    width: float = 1.3,
    depth: float = 2.6,
    full: float = 1.3,
    step: float = 0.5,
    factor: float = 2.0,
) -> dict:
    """ "near_box_nvb": near_box's box cells (`box_coarse`) bisected once per cycle (h ÷ √2,
    area ÷ 2: mark 1 of `adaptive.ZoneMarks`) instead of split into 4; the energy's marks and
    the cells of `red_layers` (3 rings, the bisections' closure included) split into 4
    (mark 2). Returns (n_cells,) int8 marks."""
    c = model.contact
    mesh = meshes[c.slave.name]
    frame = _zone_frame(model, sol, mesh)
    coarse = box_coarse(mesh, frame, factor * frame[3], width, depth, full, step)
    red = red_layers(model, sol, meshes, marked, bisect=coarse)[c.slave.name]
    return {c.slave.name: np.where(red, 2, np.where(coarse, 1, 0)).astype(np.int8)}


def zone_distance(mesh: Any, frame: tuple[float, float, float, float]) -> np.ndarray:
    """(n_cells,) the distance of each cell's centroid to the zone's surface, the segment
    |x − x_c| ≤ ℓ at y = y_top (frame of `_zone_frame`), in zone half-lengths ℓ."""
    half, xc, y_top, _ = frame
    centroid = mesh.points[mesh.cells].mean(axis=1)  # (n_cells, 2)
    dx = np.maximum(0.0, np.abs(centroid[:, 0] - xc) - half)  # (n_cells,)
    return np.hypot(dx, y_top - centroid[:, 1]) / half


def size_graded(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    factor: float = 2.0,
    full: float = 1.3,
    step: float = 0.5,
) -> dict:
    """ "size_graded": a size function around the zone: a slave cell is marked when its
    longest edge exceeds h(d) = `factor` × the zone's median segment × 2^max(0, (d − full) /
    step), d the distance of its centroid to the zone's surface in zone half-lengths
    (`zone_distance`): as fine as the surface to `full` ℓ, then twice coarser every `step`
    ℓ, everywhere (no box); then `red_layers` (3 rings)."""
    c = model.contact
    mesh = meshes[c.slave.name]
    frame = _zone_frame(model, sol, mesh)
    h = longest_edges(mesh.points[mesh.cells])  # (n_cells,)
    d = zone_distance(mesh, frame)  # (n_cells,)
    coarse = h > factor * frame[3] * 2.0 ** np.maximum(0.0, (d - full) / step)
    out = {c.slave.name: marked[c.slave.name] | coarse}
    return red_layers(model, sol, meshes, out)


def box_dorfler(model: Any, sol: Any, meshes: dict, marked: dict, theta: float = 0.6) -> dict:
    """ "box_dorfler30", "box_dorfler60": the Dörfler set (θ = 0.3, 0.6) of the energy
    estimate η_T restricted to near_box's box (`box_coarse` with size 0: every cell of the
    box), added to the marks; then `red_layers` (3 rings)."""
    c = model.contact
    mesh = meshes[c.slave.name]
    inside = box_coarse(mesh, _zone_frame(model, sol, mesh), 0.0)  # (n_cells,)
    eta = np.where(inside, _slave_eta(model, sol), 0.0)  # (n_cells,)
    out = {c.slave.name: marked[c.slave.name] | dorfler_mark(eta, theta)}
    return red_layers(model, sol, meshes, out)


class NearBoxPaced:
    """ "near_box_paced": `near_box` with its size target paced, size_k = max(factor × the
    zone's median segment, size_{k−1} / rate), so the near field's target falls by at most
    `rate` per cycle (near_box's falls by 2 with the zone's surface: its cycles grow 3–4×).
    Stateful: the last target is kept between calls and dropped when a call's mesh has fewer
    cells than the last one's (a new run)."""

    def __init__(self, rate: float = 2.0**0.5, factor: float = 2.0) -> None:
        self.rate, self.factor = rate, factor
        self.size: float | None = None
        self.n_cells = 0

    def __call__(self, model: Any, sol: Any, meshes: dict, marked: dict) -> dict:
        c = model.contact
        mesh = meshes[c.slave.name]
        if mesh.n_cells < self.n_cells:
            self.size = None
        self.n_cells = mesh.n_cells
        frame = _zone_frame(model, sol, mesh)
        size = self.factor * frame[3]
        if self.size is not None:
            size = max(size, self.size / self.rate)
        self.size = size
        out = {c.slave.name: marked[c.slave.name] | box_coarse(mesh, frame, size)}
        return red_layers(model, sol, meshes, out)


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
        m[cells[halved]] = True if m.dtype == bool else 2  # split into 4 (`ZoneMarks`)
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
    "peak_red": peak_red,
    "core_red": core_red,
    "core50_red": lambda *a: core_red(*a, fraction=0.5),
    "near_zone": near_zone,
    "near_zone50": lambda *a: near_zone(*a, radius=0.5),
    "near_zone25": lambda *a: near_zone(*a, radius=0.25),
    "zone_weighted": zone_weighted,
    "zone_weighted1": lambda *a: zone_weighted(*a, power=1.0),
    "zone_weighted_t7": lambda *a: zone_weighted(*a, theta=0.7),
    "dual": lambda *a: dual_weighted(*a, red=False),
    "dual_red": dual_weighted,
    "dual_a_red": lambda *a: dual_weighted(*a, goals=("a",)),
    "dual_red_t8": lambda *a: dual_weighted(*a, theta=0.8),
    "dual_union_red": lambda *a: dual_weighted(*a, union=True),
    "dual_union": lambda *a: dual_weighted(*a, union=True, red=False),
    "dual_peak_red": lambda m, s, ms, mk: peak_red(
        m, s, ms, dual_weighted(m, s, ms, mk, red=False)
    ),
    "layers3": red_layers,
    "near_box": near_box,
    "near_box_f2r2": lambda *a: near_box(*a, factor=2.0 * 2.0**0.5),
    "near_box_tight": lambda *a: near_box(*a, width=1.1, full=0.8, factor=2.5),
    "near_box_paced": NearBoxPaced(),
    "near_box_nvb": near_box_nvb,
    "dwr": dwr,
    "dwr_goal": lambda *a: dwr(*a, energy=False),
    "dwr_goal_pu": lambda *a: dwr(*a, energy=False, patch=True),
    "size_graded": size_graded,
    "box_dorfler30": lambda *a: box_dorfler(*a, theta=0.3),
    "box_dorfler60": box_dorfler,
    "near_level": near_level,
    "near_level4": lambda *a: near_level(*a, factor=4.0),
    "contact_w10": contact_weighted,
    "contact_w100": lambda *a: contact_weighted(*a, weight=100.0),
}
MARKS.update({f"{k}_graded": graded(v) for k, v in list(MARKS.items())})
MARKS["graded"] = graded(lambda model, sol, meshes, marked: {})
