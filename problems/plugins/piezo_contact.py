"""Plug-in: elasto-piezoelectric bodies in bilateral contact with Tresca friction (Problem 4.1).

Dual (biorthogonal) multipliers on the slave side Γ3: λ_h = Σ γ_i ψ_i n_i + α_i ψ_i τ_i, and
Λ_h = product(Free(N), Box(−g_i, g_i)) with g_i = ∫gφ_i / ∫φ_i (DESIGN.md §5). With a rigid
foundation the constraint rows are D_i n_iᵀu_i (normal) and D_i τ_iᵀu_i (tangential); with a
master body they act on the mortar jump D u_s − M u_m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fem import assembly
from fem.boundary import Trace, trace
from fem.dirichlet import expand, reduce_dirichlet
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.output import plots
from problems.scene import Scene, Table
from vi_core import METHODS, Box, Free, MixedVI, Solution, product

from . import piezo_balance
from .bodies import Body, build_body

NAME = "piezo_contact"
LOCKING_RATIO = 50.0  # λ_max/λ_min of the Voigt C; isotropic ν = 0.48 gives 50
# Two-body interfaces must coincide in the reference configuration (bilateral contact has no
# initial gap). A slave node may sit off the master polyline (distance along its normal) by at
# most SEPARATION_TOL × h, h the longest of its adjacent slave segments and the master segment
# it faces: this admits the chord-versus-arc discrepancy of a discretised curved interface
# (the sagitta h²/(8r), i.e. h/(8r) relative to h: 0.02 for the paper's mesh, < 0.1 while
# h < 0.8 r) and refuses bodies that overlap or stand apart by more.
SEPARATION_TOL = 0.1
DESCRIPTION = "elasto-piezoelectric bodies in bilateral Tresca contact (dual mortar multipliers)"


@dataclass
class Contact:
    """The contact interface Γ3: slave trace, master (None = rigid), friction bounds."""

    slave: Body
    slave_part: str
    tr: Trace  # slave trace (multiplier nodes = tr.nodes)
    master: Body | None
    master_part: str | None
    g: np.ndarray  # (N,) g_i = ∫gφ_i / ∫φ_i
    B_full: sp.csr_matrix  # (2N, n_full): normal rows then tangential rows
    g_weights: np.ndarray  # (N,) ∫ g φ_i  (= g_i D_i)
    master_proj: sp.csr_matrix | None = None  # (2N, n_full): u ↦ (D⁻¹M u_m) at slave nodes


@dataclass
class Model:
    """A built scene: the mixed VI plus what post-processing needs."""

    scene: Scene
    level: int
    bodies: list[Body]
    contact: Contact | None
    vi: MixedVI
    free: np.ndarray  # (n_free,) full indices of the unknowns
    values: np.ndarray  # (n_full,) prescribed values (fixed entries)
    options: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def unknown_fields(self) -> dict[str, np.ndarray]:
        """Boolean masks over the unknowns: which are displacement, which potential."""
        is_disp = np.zeros(self.values.size, dtype=bool)
        for b in self.bodies:
            is_disp[b.offset : b.offset + 2 * b.n_nodes] = True
        return {"displacement": is_disp[self.free], "potential": ~is_disp[self.free]}

    @property
    def dofs(self) -> dict[str, int]:
        """Number of unknowns per field."""
        counts = {k: int(v.sum()) for k, v in self.unknown_fields().items()}
        return {**counts, "multiplier": self.vi.m}

    def full(self, u: np.ndarray) -> np.ndarray:
        """Unknowns → full vector including Dirichlet values."""
        return expand(u, self.free, self.values)


def friction_weights(mesh: Mesh, part: str, tr: Trace, gfun, key: str) -> np.ndarray:
    """∫ g φ_i ds for each trace node (g ≥ 0 checked at every quadrature point)."""

    def g_checked(x, y):
        gv = gfun(x, y)
        if (gv < 0).any():
            raise SceneError(key, float(gv.min()), "a friction bound g ≥ 0 everywhere on Γ3")
        return gv

    return assembly.boundary_load(mesh, part, g_checked, 1)[tr.nodes]


def _split_ref(t: Table, key: str, bodies: dict[str, Body]) -> tuple[Body, str]:
    ref = t.string(key)
    if "." not in ref:
        raise SceneError(t.key(key), ref, "BODY.BOUNDARY, e.g. block.bottom")
    bname, part = ref.split(".", 1)
    if bname not in bodies:
        raise SceneError(t.key(key), ref, f"a body of this scene: {', '.join(bodies)}")
    body = bodies[bname]
    if part not in body.mesh.boundaries:
        raise SceneError(
            t.key(key), ref, f"a boundary of {bname!r}: {', '.join(sorted(body.mesh.boundaries))}"
        )
    return body, part


def build(scene: Scene, level: int | None = None) -> Model:
    """Scene → Model (mesh, assembly, Dirichlet reduction, contact, MixedVI).

    Any SceneError raised while building names the scene file.
    """
    try:
        with np.errstate(all="ignore"):
            return _build(scene, level)
    except SceneError as err:
        raise (err if err.file else err.in_file(scene.path)) from None


def _build(scene: Scene, level: int | None) -> Model:
    root = scene.root()
    head = root.table("scene")
    head.string("title", "")
    head.string("description", "")
    head.string("plugin", NAME, choices=(NAME,))
    default_level = head.integer("level", 1, lo=0, hi=12)
    head.finish()
    level = default_level if level is None else level
    bt = root.table("bodies")
    if not bt.data:
        raise SceneError("bodies", {}, "at least one [bodies.NAME] table")
    bodies: dict[str, Body] = {}
    offset = 0
    for name in list(bt.data):
        tb = bt.table(name)
        body = build_body(name, tb, level, offset)
        bodies[name] = body
        offset += body.size
    n_full = offset
    ct = root.table("contact", required=False)
    contact = None
    if ct is not None:
        slave, slave_part = _split_ref(ct, "slave", bodies)
        master = None
        if ct.raw("master", "rigid") != "rigid":
            master, master_part = _split_ref(ct, "master", bodies)
            if master is slave:
                raise SceneError(ct.key("master"), ct.raw("master"), "a body other than the slave")
        g_fun = ct.field("g", 1)
        ct.finish()
        if master is None:
            contact = _rigid_contact(slave, slave_part, g_fun, ct.key("g"), n_full)
        else:
            contact = _mortar_contact(
                slave, slave_part, master, master_part, g_fun, ct.key("g"), n_full
            )

    out = root.table("output", required=False)
    options = {"potential_along": None}
    if out is not None:
        if out.has("potential_along"):
            b, part = _split_ref(out, "potential_along", bodies)
            if not b.has_potential:
                raise SceneError(
                    out.key("potential_along"),
                    f"{b.name}.{part}",
                    "a boundary of a piezoelectric body",
                )
            options["potential_along"] = (b.name, part)
        out.finish()
    solver = root.table("solver", required=False)
    if solver is not None:
        options["method"] = solver.string("method", "ssn", choices=METHODS)
        options["tol"] = solver.number("tol", 1e-10, lo=0.0, lo_open=True)
        solver.finish()
    root.raw("exact", None)  # optional exact solution, read by `mixvi study`
    root.finish()

    A_full = sp.block_diag([b.A for b in bodies.values()], format="csr")
    f_full = np.concatenate([b.f for b in bodies.values()])
    fixed = np.concatenate([b.fixed for b in bodies.values()])
    values = np.concatenate([b.values for b in bodies.values()])
    X_full = sp.block_diag([b.X for b in bodies.values()], format="csr")
    _check_finite(A_full, f_full, values, contact)
    A, f, free = reduce_dirichlet(A_full, f_full, fixed, values)
    if contact is None:  # no contact: no multipliers
        B, gap, Lam, Y = sp.csr_matrix((0, free.size)), None, product(), sp.csr_matrix((0, 0))
    else:
        B, gap, Lam, Y = _contact_rows(contact, free, fixed, values)
    vi = MixedVI(
        A=A,
        B=B,
        f=f,
        Lambda=Lam,
        gap=gap,
        X=X_full[free][:, free],
        Y=Y,
        info={"scene": scene.name, "level": level},
    )
    model = Model(scene, level, list(bodies.values()), contact, vi, free, values, options)
    for b in model.bodies:
        ev = np.linalg.eigvalsh(b.material.C)
        if ev[-1] / ev[0] > LOCKING_RATIO:
            model.warnings.append(
                f"body {b.name!r}: nearly incompressible material (eigenvalue ratio of C "
                f"{ev[-1] / ev[0]:.3g} > {LOCKING_RATIO:g}); lowest-order elements lock — "
                "displacements are underestimated on coarse meshes"
            )
    return model


def _check_finite(A_full: sp.csr_matrix, f_full, values, contact: Contact | None) -> None:
    """Refuse data that overflow in assembly (each number finite, their products not)."""
    parts = {"stiffness (materials)": A_full.data, "loads": f_full, "Dirichlet values": values}
    if contact is not None:
        parts["friction bound g"] = contact.g_weights
    for what, arr in parts.items():
        if not np.isfinite(arr).all():
            raise SceneError(
                "(scene)", what, "data whose assembled system is finite (magnitudes overflow)"
            )


def _contact_rows(contact: Contact, free, fixed, values):
    """B restricted to the unknowns, the gap from Dirichlet data, Λ_h and the Y Gram matrix."""
    B = contact.B_full[:, free]
    gap = -(contact.B_full[:, fixed] @ values[fixed])
    rowsum = np.asarray(abs(B).sum(axis=1)).ravel()
    tr = contact.tr
    if (rowsum == 0).any():
        node = tr.nodes[int(np.flatnonzero(rowsum == 0)[0]) % tr.size]
        raise SceneError(
            "contact.slave",
            f"{contact.slave.name}.{contact.slave_part}",
            f"a contact boundary whose nodes are not clamped (node {node} at "
            f"{contact.slave.mesh.points[node].tolist()} has all displacement dofs prescribed)",
        )
    N = tr.size
    Lam = product(Free(N), Box(-contact.g, contact.g))
    h_i = np.zeros(N)
    np.maximum.at(h_i, tr.segments[:, 0], tr.lengths)
    np.maximum.at(h_i, tr.segments[:, 1], tr.lengths)
    Y = sp.diags(np.tile(h_i * tr.weights, 2))  # mesh-dependent H^{-1/2} stand-in
    return B, gap, Lam, Y


def _rigid_contact(slave: Body, part: str, g_fun, gkey: str, n_full: int) -> Contact:
    tr = trace(slave.mesh, part)
    N = tr.size
    gw = friction_weights(slave.mesh, part, tr, g_fun, gkey)
    dofs = slave.u_dofs(tr.nodes)  # (N, 2)
    rows = np.repeat(np.arange(2 * N), 2)
    cols = np.concatenate([dofs, dofs]).ravel()
    vals = np.concatenate(
        [tr.weights[:, None] * tr.normals, tr.weights[:, None] * tr.tangents]
    ).ravel()
    B = sp.csr_matrix((vals, (rows, cols)), shape=(2 * N, n_full))
    return Contact(slave, part, tr, None, None, gw / tr.weights, B, gw)


def _mortar_contact(
    slave: Body, part: str, master: Body, mpart: str, g_fun, gkey: str, n_full: int
) -> Contact:
    """Rows D_i n_iᵀu_s,i − Σ_k M_ik n_iᵀu_m,k (normal) and the same with τ_i (tangential)."""
    from fem.mortar import mortar_coupling

    tr = trace(slave.mesh, part)
    _check_separation(slave, part, tr, tr.normals, master, mpart)
    mort = mortar_coupling(slave.mesh, part, master.mesh, mpart, ends="keep")
    if (mort.coverage < 1 - 1e-12).any():
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}",
            f"a master boundary that covers the whole slave boundary {slave.name}.{part} "
            f"(covered fraction of the worst slave segment: {mort.coverage.min():.3f})",
        )
    assert np.array_equal(tr.nodes, mort.slave_nodes) and np.allclose(tr.weights, mort.D)
    N = tr.size
    gw = friction_weights(slave.mesh, part, tr, g_fun, gkey)
    n, t = mort.normals, mort.tangents  # (N, 2)
    sdofs = slave.u_dofs(mort.slave_nodes)  # (N, 2)
    mdofs = master.u_dofs(mort.master_nodes)  # (nm, 2)
    Ds = mort.Ds.tocoo()
    M = mort.M.tocoo()
    rows, cols, vals, prow, pcols, pvals = [], [], [], [], [], []
    for block, vec in ((0, n), (1, t)):
        for c in range(2):
            rows += [block * N + Ds.row, block * N + M.row]
            cols += [sdofs[Ds.col, c], mdofs[M.col, c]]
            vals += [Ds.data * vec[Ds.row, c], -M.data * vec[M.row, c]]
            prow.append(block * N + M.row)
            pcols.append(mdofs[M.col, c])
            pvals.append(M.data * vec[M.row, c] / mort.D[M.row])
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * N, n_full)
    )
    proj = sp.csr_matrix(
        (np.concatenate(pvals), (np.concatenate(prow), np.concatenate(pcols))),
        shape=(2 * N, n_full),
    )
    return Contact(slave, part, tr, master, mpart, gw / tr.weights, B, gw, proj)


def _normal_distances(
    x: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance t from each point x_i along n_i to the polyline of segments [a_k, b_k],
    and the index of the segment hit.

    t > 0: the polyline lies outside (a gap), t < 0: behind (an overlap); the hit of smallest
    |t|, NaN where the line x_i + t n_i misses every segment. Chunked to bound memory.
    """
    out = np.full(len(x), np.nan)
    seg = np.zeros(len(x), dtype=int)
    d = b - a  # (M, 2)
    for lo in range(0, len(x), 256):
        xi, ni = x[lo : lo + 256, None, :], n[lo : lo + 256, None, :]  # (c, 1, 2)
        det = ni[..., 0] * -d[None, :, 1] + ni[..., 1] * d[None, :, 0]  # (c, M)
        r = a[None] - xi  # (c, M, 2)
        with np.errstate(all="ignore"):
            t = (r[..., 0] * -d[None, :, 1] + r[..., 1] * d[None, :, 0]) / det
            s = (ni[..., 0] * r[..., 1] - ni[..., 1] * r[..., 0]) / det
        hit = (np.abs(det) > 0) & (s >= -1e-12) & (s <= 1 + 1e-12)
        t = np.where(hit, t, np.inf)
        k = np.argmin(np.abs(t), axis=1)
        best = t[np.arange(len(k)), k]
        out[lo : lo + 256] = np.where(np.isfinite(best), best, np.nan)
        seg[lo : lo + 256] = k
    return out, seg


def _check_separation(slave: Body, part: str, tr: Trace, normals, master: Body, mpart: str) -> None:
    """SceneError if the interfaces overlap or stand apart by more than SEPARATION_TOL·h
    (h: the longer of the slave node's adjacent segments and the master segment hit)."""
    mtr = trace(master.mesh, mpart)
    P = master.mesh.points[mtr.nodes]
    t, k = _normal_distances(
        slave.mesh.points[tr.nodes], normals, P[mtr.segments[:, 0]], P[mtr.segments[:, 1]]
    )
    h = mtr.lengths[k]
    np.maximum.at(h, tr.segments[:, 0], tr.lengths)
    np.maximum.at(h, tr.segments[:, 1], tr.lengths)
    rel = t / h
    bad = np.flatnonzero(np.abs(np.nan_to_num(rel)) > SEPARATION_TOL)
    if bad.size:
        i = bad[np.argmax(np.abs(rel[bad]))]
        what = "overlap the slave body" if rel[i] < 0 else "stand apart from it"
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}",
            f"a master boundary that coincides with {slave.name}.{part} in the "
            f"reference configuration: it would {what} by {abs(t[i]):.3g} "
            f"({abs(rel[i]):.2f} × the local mesh size {h[i]:.3g}; allowed "
            f"{SEPARATION_TOL:g}) at slave node {slave.mesh.points[tr.nodes[i]].tolist()}",
        )


def warm_start(coarse: Model, coarse_sol: Solution, fine: Model) -> dict:
    """Initial guess for `fine` from the solution on the coarser level (nested iteration).

    Along Γ3 (the same curve on every level, parametrised by normalised arc length) the normal
    coefficients are interpolated, and the tangential ones through their ratio r = α/g to the
    friction bound: a fine node between two coarse slip nodes gets |r| = 1, i.e. it starts on
    the bound even where g varies, and the first Newton step starts from the coarse
    stick/slip partition instead of rediscovering it.
    """
    if coarse.contact is None or fine.contact is None:
        return {}
    tc, tf = coarse.contact.tr, fine.contact.tr
    sc, sf = tc.s / tc.s[-1], tf.s / tf.s[-1]
    Nc = tc.size
    gc, g = coarse.contact.g, fine.contact.g
    lam_n = np.interp(sf, sc, coarse_sol.lam[:Nc])
    ratio_c = np.divide(coarse_sol.lam[Nc:], gc, out=np.zeros(Nc), where=gc > 0)
    ratio = np.clip(np.interp(sf, sc, ratio_c), -1.0, 1.0)
    on_bound = np.abs(ratio) >= 1.0 - 1e-9
    ratio[on_bound] = np.sign(ratio[on_bound])
    return {"lam0": np.concatenate([lam_n, ratio * g])}


# ------------------------------------------------------------------ post-processing
def contact_state(model: Model, sol: Solution) -> dict:
    """Per-node contact quantities along Γ3 and the Lemma 4.2 check."""
    c = model.contact
    N = c.tr.size
    x_full = model.full(sol.u)
    lam_n, lam_t = sol.lam[:N], sol.lam[N:]
    Bu = c.B_full @ x_full  # (2N,) = D_i·[u]_n, D_i·[u]_τ
    jump_t = Bu[N:] / c.tr.weights  # nodal tangential (mortar) jump
    u_s = x_full[c.slave.u_dofs(c.tr.nodes)]  # (N, 2)
    ut_s = np.einsum("ij,ij->i", u_s, c.tr.tangents)
    gmax = float(c.g.max(initial=0.0))
    slip = np.abs(lam_t) >= c.g - 1e-9 * max(gmax, 1e-300)
    b_uh_lam = float(sol.lam @ Bu)
    g_abs = float(np.sum(c.g_weights * np.abs(jump_t)))
    tiny = np.finfo(float).eps * float(np.sum(c.g_weights)) * max(np.abs(x_full).max(), 1e-300)
    lemma = abs(b_uh_lam - g_abs) / max(g_abs, tiny, 1e-300)
    state = {
        "s": c.tr.s,
        "points": c.slave.mesh.points[c.tr.nodes],
        "lam_n": lam_n,
        "lam_t": lam_t,
        "g": c.g,
        "jump_t": jump_t,
        "ut_slave": ut_s,
        "slip": slip,
        "b_uh_lam": b_uh_lam,
        "int_g_abs_u": g_abs,
        "lemma_4_2": float(lemma),
    }
    if c.master_proj is not None:
        state["ut_master"] = (c.master_proj @ x_full)[N:]
    return state


def contact_warnings(state: dict) -> list[str]:
    """What a user must know about the friction bound of this solution."""
    g, lam_t = state["g"], state["lam_t"]
    if not g.any():
        return ["g = 0 on Γ3: frictionless sliding (a linear problem)"]
    if not state["slip"].any():
        used = float(np.max(np.abs(lam_t) / np.where(g > 0, g, np.inf)))
        return [
            f"no node slips: the tangential multiplier uses at most {used:.3g} of the friction "
            "bound, so the problem is tied (g above every tangential stress)"
        ]
    return []


def postprocess(model: Model, sol: Solution, outdir: Path) -> dict:
    """Write VTU fields and PNG plots into `outdir`; return the summary entries."""
    from fem.io import write_vtu

    x_full = model.full(sol.u)
    files = []
    for b in model.bodies:
        u, phi = b.split(x_full[b.offset : b.offset + b.size])
        m = b.material
        sigma, D = assembly.cell_fields(b.mesh, u.ravel(), phi, m.C, m.e, m.kappa)
        point = {"displacement": u}
        cell = {"stress": sigma}
        if phi is not None:
            point["potential"] = phi
            cell["electric_displacement"] = D
        fn = f"{b.name}.vtu"
        write_vtu(outdir / fn, b.mesh, point, cell)
        files.append(fn)
    summary: dict = {"force_balance": piezo_balance.force_balance(model, sol)}
    if model.contact is not None:
        quad = piezo_balance.lemma_4_2(model, sol)
        if quad is not None:
            summary["lemma_4_2_quadrature"] = quad
        state = contact_state(model, sol)
        files += plots.contact_plots(state, outdir, title=model.scene.name)
        n_slip = int(state["slip"].sum())
        summary["contact"] = {
            "nodes": int(state["slip"].size),
            "stick": int(state["slip"].size - n_slip),
            "slip": n_slip,
        }
        summary["lemma_4_2"] = state["lemma_4_2"]
        summary["warnings"] = contact_warnings(state)
    along = model.options.get("potential_along")
    if along is not None:
        b = next(bb for bb in model.bodies if bb.name == along[0])
        tr = trace(b.mesh, along[1])
        _, phi = b.split(x_full[b.offset : b.offset + b.size])
        files.append(
            plots.potential_plot(
                b.mesh.points[tr.nodes], tr.s, phi[tr.nodes], outdir, f"{along[0]}.{along[1]}"
            )
        )
    summary["files"] = sorted(files)
    return summary
