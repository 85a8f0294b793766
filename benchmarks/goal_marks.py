"""Goal-oriented (dual-weighted residual) marking for Hertz with the weights z − I_h z, z the
dual solution on the once uniformly refined mesh (docs/benchmarks.md, "Hertz against uniform
refinement"; the discrete-dual markings "dual_*" of `zone_marks` weight with η_T(z_h) instead).

For a goal J of the normal multiplier (the Hertz measures of `benchmarks.hertz`: the peak
pressure λ_n(0) and the half-width 2 (Σ w λ x² / Σ w λ)^½, each relative to the closed form
at the measured load, `goal_vector`), linearised at the solution's touching set R and
frozen there: on the fine mesh (every cell split into 4, P1 and dual mortar multipliers as on
the coarse one) the dual problem A z + B_Rᵀ μ = 0, B_R z = j (j = ∂J/∂λ_R) and the fine
residuals of the coarse solution (u_h prolonged, λ_h written in the fine dual basis: exact
for straight segments)

    R_u = f − A u_h − Bᵀ λ_h   (n_f,),    r_λ = gap_R − B_R u_h   (n_R,)

give J(λ_f) − J(λ_h) = zᵀ R_u + μᵀ r_λ + (B z)ᵀ λ_off for the fine solution λ_f with the
same touching set (A symmetric; λ_off: λ_h on the fine rows off R, just past the zone's
edge, which the fine problem sets to 0). The coarse equations hold, so R_u vanishes on the
coarse P1 functions and z may be replaced by z − I_h z in its term (I_h the nodal
interpolant on the coarse mesh, zero at its nodes): that term lives at the fine mesh's new
nodes, the coarse edges' midpoints. The indicator of a fine node is |Σ_c (z − I_h z)_c
R_u,c| + |its contact rows' terms|, split between the coarse cells of its coarse edge or
vertex (`_localised`; with `patch` summed per coarse vertex patch first). No
parameter is fitted: θ = 0.5 per goal (`goal_set`) as the energy loop's Dörfler marking, and
the three red rings of `zone_marks.red_layers` that keep the nodal multiplier free of its
odd-even mode. The markings: `zone_marks.MARKS` "dwr", "dwr_goal", "dwr_goal_pu" (`dwr`).

    python benchmarks/goal_marks.py NAME CYCLES A_LIMIT P0_LIMIT

prints the estimate on the Hertz scene's mesh after CYCLES − 1 refinements with marking NAME
against the once refined mesh's own solution and the limit's relative errors (`effectivity`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fem.marking import dorfler_mark

GOALS = ("p0", "a")  # the Hertz measures (`goal_vector`)


def fine_model(model: Any, mesh: Any) -> tuple[Any, Any, Any]:
    """(fine model, fine mesh, P (n_fine_nodes, n_nodes) prolongation): the scene of `model`
    rebuilt on `mesh` (the slave body's) with every cell split into 4."""
    from fem.bisection import refine_marked
    from problems.plugins import registry
    from problems.plugins.contact.bodies import given_meshes

    fine, P = refine_marked(mesh, np.ones(mesh.n_cells, dtype=bool))
    plugin = registry.for_scene(model.scene)
    with given_meshes({model.contact.slave.name: fine}):
        return plugin.build(model.scene, 0), fine, P


def _free_index(model: Any) -> np.ndarray:
    """(n_full,) the unknown's index of each full dof, −1 where prescribed."""
    out = np.full(model.values.size, -1, dtype=np.int64)
    out[model.free] = np.arange(model.free.size)
    return out


def _nodal(model: Any, v: np.ndarray, n_nodes: int) -> np.ndarray:
    """(n_nodes, 2) a vector over B's rows (normal, tangential) as values at the slave's mesh
    nodes (zero off the contact surface)."""
    c = model.contact
    out = np.zeros((n_nodes, 2))
    out[c.tr.nodes[c.rows_n], 0] = c.normal(v)
    out[c.tr.nodes[c.rows_t], 1] = c.tangential(v)
    return out


def fine_multiplier(model: Any, sol: Any, fine: Any) -> np.ndarray:
    """(m_f,) λ_h, the coarse dual-basis multiplier, in the fine model's dual basis: the fine
    row k gets ⟨λ_h, φ_k⟩ / ∫φ_k (φ_k the fine hat; B = D diagonal, a rigid master). On a
    coarse segment (a, b) of length h, with ψ_a = 2φ_a − φ_b: ⟨λ_h, φ_mid⟩ = h (λ_a + λ_b)/4,
    and on its half at a ⟨λ_h, φ_a⟩ = h (3λ_a − λ_b)/8."""
    from fem.bisection import _edges

    c, cf = model.contact, fine.contact
    n, nf = c.slave.n_nodes, cf.slave.n_nodes
    lam = _nodal(model, sol.lam, n)  # (n, 2) coarse nodal values
    seg = c.tr.nodes[c.tr.facets]  # (n_seg, 2) mesh nodes
    h = c.tr.measures[:, None]  # (n_seg, 1)
    codes = _edges(c.slave.mesh.cells, n)[0]  # (n_edges,) sorted; fine node n + k on edge k
    mid = n + np.searchsorted(codes, seg.min(axis=1).astype(np.int64) * n + seg.max(axis=1))
    la, lb = lam[seg[:, 0]], lam[seg[:, 1]]  # (n_seg, 2)
    load = np.zeros((nf, 2))  # ⟨λ_h, φ_k⟩ per fine node and row kind
    np.add.at(load, mid, h * (la + lb) / 4)
    np.add.at(load, seg[:, 0], h * (3 * la - lb) / 8)
    np.add.at(load, seg[:, 1], h * (3 * lb - la) / 8)
    w = np.ones((nf, 2))
    w[cf.tr.nodes[cf.rows_n], 0] = cf.W_n[cf.rows_n]
    w[cf.tr.nodes[cf.rows_t], 1] = cf.W_t[cf.rows_t]
    return _rows(fine, load / w)


def _rows(model: Any, nodal: np.ndarray) -> np.ndarray:
    """The inverse of `_nodal`: (m,) over B's rows from (n_nodes, 2) nodal values."""
    c = model.contact
    out = np.zeros(model.vi.B.shape[0])
    out[c.idx_n] = nodal[c.tr.nodes[c.rows_n], 0]
    out[c.idx_t] = nodal[c.tr.nodes[c.rows_t], 1]
    return out


def fine_residuals(
    model: Any, sol: Any, fine: Any, P: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R_u (n_f,), r (m_f,), λ_h on the fine rows (m_f,)) of the module docstring: the coarse
    solution's residuals in the fine model `fine` (P the nodal prolongation). R_u is zero on
    the prolonged coarse P1 functions (Galerkin orthogonality: `P_full.T @ R_u` ≈ 0)."""
    slave, fslave = model.contact.slave, fine.contact.slave
    u = model.full(sol.u)[slave.u_dofs(np.arange(slave.n_nodes))]  # (n_nodes, 2)
    u_full = fine.values.copy()  # (n_full_f,) prescribed values of the fine model
    dofs_f = fslave.u_dofs(np.arange(fslave.n_nodes))  # (n_f_nodes, 2)
    free = _free_index(fine)[dofs_f] >= 0  # (n_f_nodes, 2)
    u_full[dofs_f[free]] = (P @ u)[free]
    u_f = u_full[fine.free]  # (n_f,)
    lam_f = fine_multiplier(model, sol, fine)  # (m_f,)
    vi = fine.vi
    R_u = vi.f - vi.A @ u_f - vi.B.T @ lam_f  # (n_f,)
    r = vi.gap - vi.B @ u_f  # (m_f,)
    return R_u, r, lam_f


def fine_touching(model: Any, sol: Any, fine: Any, P: Any) -> np.ndarray:
    """(N_n_f,) bool over the fine normal rows: the coarse touching set, frozen: its nodes and
    the midpoints of segments with both ends touching."""
    c, cf = model.contact, fine.contact
    touch = np.zeros(c.slave.n_nodes)
    touch[c.tr.nodes[c.rows_n[model.contact_state(sol)["touch"]]]] = 1.0
    return (P @ touch)[cf.tr.nodes[cf.rows_n]] > 1.0 - 1e-12


def goal_vector(fine: Any, touch: np.ndarray, lam_f: np.ndarray, goal: str) -> np.ndarray:
    """(n_R,) j = ∂G/∂λ over the fine touching rows (`touch` over the normal rows) of the
    Hertz measures of `benchmarks.hertz`, relative to the closed form at the measured load
    P = Σ w λ (a_ref ∝ P^½, p0_ref ∝ P^½), linearised: "p0" G = log λ_0 − ½ log P (λ_0 at the
    row nearest x = 0), j = e_0 / λ_0 − w / (2P); "a" G = ½ log J − ½ log P with the second
    moment J = Σ w λ x² / P (a = 2 J^½), j = w (x² − 2J) / (2 J P). The load's term carries
    the block's compliance: without it the goals see only the zone (docs/benchmarks.md)."""
    c = fine.contact
    x = c.slave.mesh.points[c.tr.nodes[c.rows_n], 0][touch]  # (n_R,)
    w = c.W_n[c.rows_n][touch]  # (n_R,)
    lam = c.normal(lam_f)[touch]  # (n_R,)
    P = float(w @ lam)
    if goal == "p0":
        k = np.argmin(np.abs(x))
        j = -w / (2 * P)
        j[k] += 1.0 / lam[k]
        return j
    J = float((w * lam * x**2).sum() / P)
    return w * (x**2 - 2 * J) / (2 * J * P)


def constrained_solve(
    fine: Any, touch: np.ndarray, rhs: list[tuple[np.ndarray, np.ndarray]]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per (f (n_f,), g (n_R,)) of `rhs`: (v (n_f,), μ (m_f,), zero off the touching rows)
    with A v + B_Rᵀ μ = f, B_R v = g, by elimination (one factorisation for all): each row of
    B_R is one entry W_k at one unknown (a flat surface's normal, dual mortar D), so v there
    is g / W and μ = (f − A v) / W there; the rest is A's SPD block (SuperLU in symmetric
    mode, `vi_core.linalg.superlu`). The saddle-point matrix itself (A ~ E, W ~ h) lost
    digits of μ in a direct solve; CG with smoothed aggregation took as long as this (41
    iterations to 1e-6 at 262,583 unknowns). ValueError for a row of B_R with more than one
    entry."""
    from vi_core.linalg import ORDERING, superlu

    rows = fine.contact.idx_n[touch]  # (n_R,)
    B = fine.vi.B[rows].tocsr()  # (n_R, n_f)
    if (np.diff(B.indptr) != 1).any():
        raise ValueError("constrained_solve: each touching row of B must be one entry")
    col, W = B.indices, B.data  # (n_R,) each
    A = fine.vi.A.tocsr()
    rest = np.setdiff1d(np.arange(A.shape[0]), col)  # (n_f − n_R,)
    solve = superlu(A[rest][:, rest].tocsc(), ORDERING, None).solve
    A_rc = A[rest][:, col]  # (n_f − n_R, n_R)
    out = []
    for f, g in rhs:
        v = np.zeros(A.shape[0])
        v[col] = g / W
        v[rest] = solve(f[rest] - A_rc @ v[col])
        mu = np.zeros(fine.vi.B.shape[0])
        mu[rows] = (f - A @ v)[col] / W
        out.append((v, mu))
    return out


def _coarse_part(fine: Any, P: Any, v_free: np.ndarray) -> np.ndarray:
    """(n_f,) v − I_h v over the fine unknowns: the nodal interpolant on the coarse mesh
    (through its nodes, the first P.shape[1] of the fine mesh) subtracted."""
    fs = fine.contact.slave
    full = np.zeros(fine.values.size)
    full[fine.free] = v_free
    dofs = fs.u_dofs(np.arange(fs.n_nodes))  # (n_f_nodes, 2)
    nodal = full[dofs]  # (n_f_nodes, 2)
    full[dofs] = nodal - P @ nodal[: P.shape[1]]
    return full[fine.free]


def midpoint_indicators(
    model: Any,
    sol: Any,
    mesh: Any,
    fine: Any,
    P: Any,
    goals: tuple[str, ...] = GOALS,
    patch: bool = False,
) -> dict[str, tuple[np.ndarray, float]]:
    """Per goal: ((n_cells,) η_T ≥ 0 of the module docstring, the signed estimate of
    J(λ_f) − J(λ_h), λ_f the fine solution with the touching set frozen: exact for it) on the
    coarse `mesh` (the slave's)."""
    R_u, r, lam_f = fine_residuals(model, sol, fine, P)
    touch = fine_touching(model, sol, fine, P)
    js = [goal_vector(fine, touch, lam_f, goal) for goal in goals]
    duals = constrained_solve(fine, touch, [(np.zeros(R_u.size), j) for j in js])
    off = np.zeros(lam_f.size, dtype=bool)  # (m_f,) normal rows off the frozen set
    off[fine.contact.idx_n[~touch]] = True
    lam_off = np.where(off, lam_f, 0.0)  # λ_h there: the fine problem has 0
    return {
        goal: _localised(fine, P, mesh, R_u, r, lam_off, z, mu, patch)
        for goal, (z, mu) in zip(goals, duals, strict=True)
    }


def _localised(
    fine: Any,
    P: Any,
    mesh: Any,
    R_u: np.ndarray,
    r: np.ndarray,
    lam_off: np.ndarray,
    z: np.ndarray,
    mu: np.ndarray,
    patch: bool = False,
) -> tuple[np.ndarray, float]:
    """((n_cells,) η_T, the signed estimate) of one dual solution (`midpoint_indicators`):
    J(λ_f) − J(λ_h) = (z − I_h z)ᵀ R_u + μᵀ r + (B z)ᵀ λ_off, the first term per fine node
    (the coarse edges' midpoints), the others per fine contact row (λ_off: λ_h on the rows
    off the frozen set, which the fine problem sets to 0); each node's |term| split evenly
    between the coarse cells at its coarse edge or vertex. With `patch` the signed terms are
    first summed per coarse vertex a with the coarse hat ψ_a as weight (ψ_a = ½ at its
    edges' midpoints: Pᵀ; a partition of unity, Richter and Wick 2015), |that| split evenly
    between the cells at a: the terms' signs cancel within a vertex patch."""
    from fem.bisection import _edge_cells, _edges

    fs = fine.contact.slave
    n_f, n = fs.n_nodes, mesh.n_nodes
    full = np.zeros(fine.values.size)
    full[fine.free] = _coarse_part(fine, P, z) * R_u
    node_u = full[fs.u_dofs(np.arange(n_f))].sum(axis=1)  # (n_f_nodes,) Σ_c w_c R_c
    rows = mu * r + (fine.vi.B @ z) * lam_off  # (m_f,)
    node_c = _nodal(fine, rows, n_f).sum(axis=1)  # (n_f_nodes,)
    estimate = float(node_u.sum() + node_c.sum())
    if patch:
        return spread(mesh, np.abs(P.T @ (node_u + node_c))), estimate  # the patch sums
    eta = np.abs(node_u) + np.abs(node_c)  # (n_f_nodes,)
    out = spread(mesh, eta[:n])
    # fine node n + k is the midpoint of the coarse edge k (all edges bisected, in code order)
    codes, cell_edges = _edges(mesh.cells, n)  # (n_edges,), (n_cells, 3)
    cells = _edge_cells(cell_edges, codes.size)  # (n_edges, 2), −1 for none
    two = cells[:, 1] >= 0  # (n_edges,)
    e = eta[n:] / np.where(two, 2.0, 1.0)  # (n_edges,)
    np.add.at(out, cells[:, 0], e)
    np.add.at(out, cells[two, 1], e[two])
    return out, estimate


def spread(mesh: Any, values: np.ndarray) -> np.ndarray:
    """(n_cells,) per-vertex values (n_nodes,) split evenly between the cells at each vertex
    (their sum kept)."""
    valence = np.bincount(mesh.cells.ravel(), minlength=mesh.n_nodes)  # (n_nodes,)
    out = np.zeros(mesh.n_cells)
    share = np.divide(values, valence, out=np.zeros(mesh.n_nodes), where=valence > 0)
    np.add.at(out, np.arange(mesh.n_cells).repeat(3), share[mesh.cells.ravel()])
    return out


def goal_set(eta: np.ndarray, theta: float) -> np.ndarray:
    """(n_cells,) bool: the smallest set M with Σ_M η_T ≥ θ Σ η_T (ties completed), η_T ≥ 0
    (n_cells,) shares of a goal's error itself, not of a square: `dorfler_mark` of η_T^½
    (of η_T, on Hertz, it marked one or two cells at the zone's edge or centre)."""
    return dorfler_mark(np.sqrt(eta), theta)


def dwr(
    model: Any,
    sol: Any,
    meshes: dict,
    marked: dict,
    theta: float = 0.5,
    energy: bool = True,
    rings: int = 3,
    patch: bool = False,
) -> dict:
    """ "dwr": per goal of `GOALS` the bulk set (`goal_set`, θ) of `midpoint_indicators`,
    added to the energy's marks (with `energy`; else instead of them), then
    `zone_marks.red_layers` with `rings` rings; `patch`: the indicators localised by vertex
    patches (`_localised`)."""
    from benchmarks.zone_marks import red_layers

    name = model.contact.slave.name
    mesh = meshes[name]
    fine, _, P = fine_model(model, mesh)
    m = marked[name].copy() if energy else np.zeros(mesh.n_cells, dtype=bool)
    for eta, _ in midpoint_indicators(model, sol, mesh, fine, P, patch=patch).values():
        m |= goal_set(eta, theta)
    return red_layers(model, sol, meshes, {name: m}, rings=int(rings))


def effectivity(name: str, cycles: int, limit: tuple[float, float]) -> dict:
    """The estimate on the Hertz scene's last mesh of `cycles` adaptive cycles with marking
    `name` (of `zone_marks.MARKS`) against the once refined mesh's own solution and the
    limit's (a, p0) relative errors `limit`: per goal {"estimate", "fine", "limit"}, each a
    change of G from the cycle's solution, and "terms", Σ η_T (the terms' sizes before their
    cancellation), plus "unknowns", "fine_unknowns"."""
    from benchmarks import hertz
    from benchmarks.zone_marks import MARKS
    from problems import pipeline
    from problems.pipeline import adaptive
    from problems.plugins.contract import solve_model

    loaded = pipeline.load("hertz")
    options = {"method": "ssn", "tol": 1e-10}
    model, sol, _, _ = adaptive.adapt(
        loaded.plugin,
        loaded.scene,
        1e-9,
        max_cycles=cycles,
        solve_options=options,
        contact_zone=MARKS[name],
    )
    mesh = model.contact.slave.mesh
    fine, _, P = fine_model(model, mesh)
    out = midpoint_indicators(model, sol, mesh, fine, P, patch=name.endswith("_pu"))
    fsol = solve_model(loaded.plugin, fine, **options)
    coarse, refined = (hertz.of_model(m, s, 1.0).errors for m, s in ((model, sol), (fine, fsol)))
    row: dict = {"unknowns": int(sum(model.dofs.values())), "fine_unknowns": fine.vi.A.shape[0]}
    for goal, lim in zip(("a", "p0"), limit, strict=True):
        base = np.log1p(coarse[goal])
        row[goal] = {
            "estimate": out[goal][1],
            "fine": float(np.log1p(refined[goal]) - base),
            "limit": float(np.log1p(lim) - base),
            "terms": float(out[goal][0].sum()),
        }
    return row


if __name__ == "__main__":  # python benchmarks/goal_marks.py NAME CYCLES A_LIMIT P0_LIMIT
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    name, cycles, a_lim, p0_lim = sys.argv[1:5]
    row = effectivity(name, int(cycles), (float(a_lim), float(p0_lim)))
    print(f"{name}, {row['unknowns']} unknowns (fine {row['fine_unknowns']}):")
    for goal in ("a", "p0"):
        r = row[goal]
        print(
            f"  G_{goal}: estimate {r['estimate']:+.3e}, fine − coarse {r['fine']:+.3e}, "
            f"limit − coarse {r['limit']:+.3e}; Σ η_T {r['terms']:.3e}"
        )
