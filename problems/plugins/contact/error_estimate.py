"""A posteriori error estimator of the contact plug-in in 2D (`plane`): per cell η_T.

Residual-type, after Wohlmuth (dual mortar multipliers), Hild and Nicaise (residual
estimators for Signorini/Tresca contact) and Weiss and Wohlmuth (frictional contact with
mortars): for each body, with the flux F_h = (σ_h, −D_h), σ = Cε(u) + eᵀ∇φ, D = eε(u) − κ∇φ
(`fem.estimator`, the sign convention of `fem.assembly`),

    η_T² = (1/c_u) [h_T² ‖f + div σ_h‖² + ½ Σ h_E ‖[σ_h n]‖² + Σ_{E ⊂ Γ_N} h_E ‖t − σ_h n‖²
                    + Σ_{E ⊂ Γ_C slave} h_E ‖σ_h n + λ_h‖² + h_E ‖(|λ_t,h| − G)_+‖²]
         + (1/c_φ) [the same for D with the free charge q and the surface charge s]
         + Σ_{E ⊂ Γ_C slave} [∫_E (G |s_h| − λ_t,h s_h)_+ + ∫_E λ_n,h⁻ ... see TERMS]
         + c_u Σ_{E ⊂ Γ_C slave} h_E⁻¹ ‖(normal defect)‖²_E

with c_u = λ_max(C), c_φ = λ_max(κ) (the residuals of an operator a·∇ weighted by 1/a make
η_T² an energy: Bernardi and Verfürth's weighting), λ_h = Σ_k ψ̃_k (γ_k n_k + α_k τ_k) the
multiplier as a function (λ = −σn on Γ3), s_h the slip (tangential displacement of the slave
relative to the master or the rigid foundation), G the friction bound (g, or F λ_n),
and the normal defect: u_n,h − gap (bilateral: the whole defect, the constraint holds only
weakly with a master body; unilateral: the penetration (u_n,h − gap)_+).

Dirichlet components of a boundary part contribute nothing; the exterior facets that no part
names are traction-free and charge-free. The contact facets of a master body carry the
mechanical flux residual against the slave's λ_h only through the mortar coupling: that term
is not included (the slave's h_E ‖σ_h n + λ_h‖² and the normal defect carry the interface).

`TERMS` names the contact terms; `estimate(..., drop=name)` leaves one out (mutation tests).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fem.estimator import (
    boundary_indicator,
    energy_error,
    facet_fluxes,
    jump_indicator,
    volume_indicator,
)
from fem.facets import SEGMENT_DUAL, facet_values
from fem.locate import evaluate
from vi_core import Solution

from ..contract import Indicator
from .bodies import COMPONENTS, vector
from .separation import to_master

# the contact terms (module docstring): flux against λ_h, friction bound, complementarity of
# the friction law, normal defect (penetration or weak-constraint defect)
TERMS = ("flux", "friction", "complementarity", "normal")


def flux_map(C: np.ndarray, e: np.ndarray | None, kappa: np.ndarray | None) -> np.ndarray:
    """L (c·2, c·2): vec F = L vec ∇U for U = (u_x, u_y[, φ]) and F = (σ[, −D]) (2D, Voigt
    order xx, yy, xy with engineering shear)."""
    c = 2 if e is None else 3
    L = np.zeros((2 * c, 2 * c))
    for j in range(2 * c):
        G = np.zeros((c, 2))
        G.flat[j] = 1.0
        eps = np.array([G[0, 0], G[1, 1], G[0, 1] + G[1, 0]])  # (3,) Voigt strain
        s = C @ eps  # (3,)
        F = np.zeros((c, 2))
        if e is not None:
            s = s + e.T @ G[2]
            F[2] = kappa @ G[2] - e @ eps  # −D
        F[:2] = [[s[0], s[2]], [s[2], s[1]]]
        L[:, j] = F.ravel()
    return L


def energy_map(C: np.ndarray, kappa: np.ndarray | None) -> np.ndarray:
    """S (c·2, c·2): vec∇eᵀ S vec∇e = ε(e)ᵀCε(e) + ∇e_φᵀκ∇e_φ, the energy norm (the coupling
    cancels in the operator's symmetric part)."""
    S = flux_map(C, None if kappa is None else np.zeros((2, 3)), kappa)
    return 0.5 * (S + S.T)


def _weights(material: Any) -> np.ndarray:
    """(c,) 1/c_u per displacement component, 1/c_φ for the potential."""
    w = [1.0 / np.linalg.eigvalsh(material.C)[-1]] * 2
    if material.piezoelectric:
        w.append(1.0 / np.linalg.eigvalsh(material.kappa)[-1])
    return np.array(w)


def _source(t: Any, c: int):
    """The body's volume source (x, y) → (..., c): body force, free charge (None: none)."""
    if t.body_force is None and (c == 2 or t.free_charge is None):
        return None

    def f(x, y):
        shape = np.broadcast(x, y).shape
        out = np.zeros((*shape, c))
        if t.body_force is not None:
            out[..., :2] = vector(t.body_force)(x, y)
        if c == 3 and t.free_charge is not None:
            out[..., 2] = t.free_charge(x, y)
        return out

    return f


def _nodal(model: Any, sol: Solution) -> dict[str, np.ndarray]:
    """Per body: nodal fields U (N, c) = (u_x, u_y[, φ])."""
    x = model.full(sol.u)
    out = {}
    for b in model.bodies:
        u, phi = b.split(x[b.offset : b.offset + b.size])
        out[b.name] = u if phi is None else np.column_stack([u, phi])
    return out


def _multiplier_at(contact: Any, lam: np.ndarray, seg: np.ndarray, t: np.ndarray):
    """λ_h·n-frame parts at points t ∈ [0, 1] of trace segments `seg` (both (M,)): the
    vector λ_h (M, 2), its normal part γ (M,) and tangential part α (M,) (nodal frames
    interpolated by the dual functions)."""
    tr, seg, t = contact.tr, np.ravel(seg), np.ravel(t)
    gam = (contact.Q_n.T @ contact.normal(lam)).reshape(-1, 2)  # (n_seg, 2)
    alp = (contact.Q_t.T @ contact.tangential(lam)).reshape(-1, 2)  # (n_seg, 2)
    psi = facet_values("line", t[:, None]) @ SEGMENT_DUAL.T  # (M, 2) ψ_a
    nodes = tr.facets[seg]  # (M, 2) trace indices
    n, tau = tr.normals[nodes], tr.tangents[nodes]  # (M, 2, 2)
    g_a, a_a = gam[seg], alp[seg]  # (M, 2) per local function
    vec = np.einsum("ma,ma,mad->md", psi, g_a, n) + np.einsum("ma,ma,mad->md", psi, a_a, tau)
    return vec, np.einsum("ma,ma->m", psi, g_a), np.einsum("ma,ma->m", psi, a_a)


def _on_trace(contact: Any, mesh_nodes: np.ndarray, t: np.ndarray):
    """Trace segment and its parameter (M,) of points at parameter t (q,) of facets given by
    their sorted nodes `mesh_nodes` (n_b, 2): (seg (n_b, q), t_seg (n_b, q))."""
    tr = contact.tr
    glob = tr.nodes[tr.facets]  # (n_seg, 2) global nodes of each trace segment
    key = {tuple(sorted(p)): s for s, p in enumerate(glob.tolist())}
    seg = np.array([key[tuple(p)] for p in mesh_nodes.tolist()])  # (n_b,)
    forward = glob[seg, 0] == mesh_nodes[:, 0]  # (n_b,) the trace runs from the smaller node
    ts = np.where(forward[:, None], t[None, :], 1.0 - t[None, :])  # (n_b, q)
    return np.broadcast_to(seg[:, None], ts.shape), ts


def estimate(spec_model: Any, model: Any, sol: Solution) -> dict[str, Indicator]:
    """The plug-in declaration `estimate` (`problems.plugins.contract`): per body its mesh, η_T
    (`indicators`) and the energy ‖U_h‖² (`energy_map`); `spec_model` is the plug-in's
    SCENE_MODEL (`plane`: `estimate = partial(error_estimate.estimate, SCENE_MODEL)`)."""
    eta = indicators(spec_model, model, sol)
    spec = _spec(spec_model, model)
    U = _nodal(model, sol)
    out = {}
    for b in model.bodies:
        S = energy_map(b.material.C, b.material.kappa)
        zero = np.zeros((U[b.name].shape[1], b.dim))
        order = 1 if b.mesh.cells.shape[1] == b.dim + 1 else 2  # exact: ∇U_h const. / bilinear
        energy = energy_error(
            b.mesh,
            U[b.name],
            S,
            lambda *p, z=zero: np.broadcast_to(z, (*np.shape(p[0]), *z.shape)),
            order,
        )
        curves = spec.bodies[b.name].geometry.curves()
        out[b.name] = Indicator(b.mesh, eta[b.name], float(energy.sum()), curves)
    return out


def _spec(spec_model: Any, model: Any) -> Any:
    """The validated scene model (`indicators`' `spec_model`)."""
    if isinstance(spec_model, type):
        return model.scene.validated(spec_model)
    return spec_model(model.scene)


def indicators(
    spec_model: Any,
    model: Any,
    sol: Solution,
    drop: str | None = None,
    flip: str | None = None,
) -> dict[str, np.ndarray]:
    """dict body name → (n_cells,) η_T of the module docstring (mutation tests: `drop`, one of
    TERMS left out; `flip`, one of TERMS with the sign of λ_h or of the defect inside it
    reversed: σ_h n − λ_h, (G − |λ_t|)_+, (G|s_h| + λ_t s_h)_+, g − u_n). `spec_model`: the
    plug-in's SCENE_MODEL, or a function scene → its contact scene model (signorini:
    `signorini.piezo_spec`)."""
    for arg, value in (("drop", drop), ("flip", flip)):
        if value is not None and value not in TERMS:
            raise ValueError(f"{arg} must be one of {TERMS}, got {value!r}")
    spec = _spec(spec_model, model)
    U = _nodal(model, sol)
    eta2 = {}
    for b in model.bodies:
        t = spec.bodies[b.name]
        m = b.material
        L = flux_map(m.C, m.e, m.kappa)
        w = _weights(m)  # (c,)
        c = w.size
        ff = facet_fluxes(b.mesh, U[b.name], L)
        n = b.mesh.n_cells
        e2 = jump_indicator(ff, n, w)
        e2 += volume_indicator(b.mesh, U[b.name], L, _source(t, c), w)
        # exterior facets: R = data − F_h n (data 0 unless a part gives it), per component
        ext = np.flatnonzero(~ff.interior)
        R = np.zeros((ff.flux.shape[0], ff.flux.shape[1], c))  # (n_i, q, c) on all instances
        R[ext] = -ff.flux[ext]
        active = np.zeros((ff.flux.shape[0], c), dtype=bool)
        active[ext] = True
        for part in t.traction:
            i = ff.on(b.mesh.boundaries[part.boundary])
            R[i, :, :2] += np.asarray(vector(part.value)(*np.moveaxis(ff.x[i], -1, 0)))
        for part in t.charge:  # F = −D: the Neumann datum of −D·n is −s
            i = ff.on(b.mesh.boundaries[part.boundary])
            R[i, :, 2] -= np.broadcast_to(
                part.value(*np.moveaxis(ff.x[i], -1, 0)), R[i, :, 2].shape
            )
        for part in t.displacement:
            active[
                ff.on(b.mesh.boundaries[part.boundary])[:, None], COMPONENTS[part.components]
            ] = False
        for part in t.potential:
            active[ff.on(b.mesh.boundaries[part.boundary]), 2] = False
        ct = model.contact
        if ct is not None and ct.master is b:  # see the module docstring
            active[ff.on(b.mesh.boundaries[ct.master_part]), :2] = False
        contact_cells = np.zeros(n)
        if ct is not None and ct.slave is b:
            i = ff.on(b.mesh.boundaries[ct.slave_part])
            terms = _contact_terms(spec.contact, ct, ff, i, sol, U, w, flip)
            for name, val in terms.items():
                if name != drop:
                    contact_cells += val
            if drop == "flux":
                active[i, :2] = False
            else:  # σ_h n + λ_h on the slave's contact facets, all components
                lam_vec = _multiplier_at(ct, sol.lam, *_on_trace(ct, ff.nodes[i], ff.t[:, 0]))[0]
                sign = -1.0 if flip == "flux" else 1.0
                R[i, :, :2] = -(ff.flux[i, :, :2] + sign * lam_vec.reshape(R[i, :, :2].shape))
                active[i, :2] = True
        R = R * np.sqrt(w) * active[:, None, :]
        e2 += boundary_indicator(ff, ext, R[ext], n) + contact_cells
        eta2[b.name] = e2
    return {k: np.sqrt(v) for k, v in eta2.items()}


def _field(expr: Any, x: np.ndarray) -> np.ndarray:
    """(M,) a scalar scene expression at the points x (M, 2)."""
    return np.broadcast_to(np.asarray(expr(x[:, 0], x[:, 1]), dtype=float), x.shape[:1])


def _master_side(
    section: Any, ct: Any, x: np.ndarray, nrm: np.ndarray, U: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The other side seen from the slave points x (M, 2) with outward normals nrm (M, 2):
    (gap (M,), behind (M,) bool, its displacement (M, 2)). A rigid foundation: the scene's gap
    (0 without one), behind everywhere, at rest. A master body: the point y = x + t n where
    the slave normal meets the master boundary (`separation.to_master`), u_m(y), gap = t for
    unilateral contact (the bodies may start apart) and 0 for bilateral (its rows close the
    gap); where the normal misses the master, no master lies behind (behind False: no slip,
    no defect; the multiplier is 0 on such segments, whose nodes are uncovered)."""
    u_m = np.zeros_like(x)  # (M, 2)
    if ct.master is None:
        gap = np.zeros(len(x)) if section.gap is None else _field(section.gap, x)
        return gap, np.ones(len(x), dtype=bool), u_m
    t, _, _ = to_master(x, nrm, ct.master, ct.master_part)  # (M,)
    behind = np.isfinite(t)
    y = x[behind] + t[behind, None] * nrm[behind]  # (M_b, 2) on the master boundary
    u_m[behind] = evaluate(ct.master.mesh, U[ct.master.name][:, :2], y)
    gap = np.where(behind, t, 0.0) if ct.law == "unilateral" else np.zeros(len(x))
    return gap, behind, u_m


def _contact_terms(
    section: Any,
    ct: Any,
    ff: Any,
    i: np.ndarray,
    sol: Solution,
    U: dict,
    w: np.ndarray,
    flip: str | None = None,
) -> dict[str, np.ndarray]:
    """(n_cells,) per contact term of TERMS but "flux" (which acts on the facet residual):
    friction bound, complementarity of the friction law, normal defect; `section` is the
    scene's [contact] table (the bound's and the gap's expressions); `flip`: see
    `indicators`."""
    n_cells = ct.slave.mesh.n_cells
    seg, ts = _on_trace(ct, ff.nodes[i], ff.t[:, 0])  # (n_b, q) each
    _, gam, alp = _multiplier_at(ct, sol.lam, seg.ravel(), ts.ravel())  # (n_b q,) each
    x = ff.x[i].reshape(-1, 2)  # (n_b q, 2)
    nrm = ff.normal[i].reshape(-1, 2)  # (n_b q, 2) outward of the slave
    tau = np.stack([-nrm[:, 1], nrm[:, 0]], axis=1)  # τ = (−n_y, n_x) as `fem.facets.frames`
    gap, behind, u_m = _master_side(section, ct, x, nrm, U)  # (n_b q,), (n_b q,), (n_b q, 2)
    rel = evaluate(ct.slave.mesh, U[ct.slave.name][:, :2], x) - u_m  # (n_b q, 2) the jump
    slip = np.where(behind, np.einsum("md,md->m", rel, tau), 0.0)  # (n_b q,)
    un = np.einsum("md,md->m", rel, nrm)
    bound = _field(section.g if ct.friction == "tresca" else section.F, x)  # (n_b q,)
    if ct.friction == "coulomb":
        bound = bound * np.maximum(gam, 0.0)
    elif ct.law == "unilateral":
        bound = bound * (gam > 0)
    shape = ff.w[i].shape  # (n_b, q)
    wq, h = ff.w[i], ff.h[i][:, None]  # (n_b, q), (n_b, 1)
    sf = -1.0 if flip == "friction" else 1.0
    friction = np.maximum(sf * (np.abs(alp) - bound), 0.0).reshape(shape)
    sc = -1.0 if flip == "complementarity" else 1.0
    compl = np.maximum(bound * np.abs(slip) - sc * alp * slip, 0.0).reshape(shape)
    defect = np.where(behind, (-1.0 if flip == "normal" else 1.0) * (un - gap), 0.0)
    defect = defect.reshape(shape)
    if ct.law != "bilateral":
        defect = np.maximum(defect, 0.0)
    out = {}
    for name, per_point in (
        ("friction", w[0] * h * friction**2),
        ("complementarity", compl),
        ("normal", defect**2 / (w[0] * h)),
    ):
        v = np.zeros(n_cells)
        np.add.at(v, ff.cell[i], (wq * per_point).sum(axis=1))
        out[name] = v
    return out


def energy_errors(model: Any, sol: Solution) -> dict[str, np.ndarray] | None:
    """dict body name → (n_cells,) the squared energy-norm error per cell against the scene's
    [exact] table (`energy_map`; None without one): the quantity η estimates."""
    from problems.scene.exact import split_exact

    _, exact = split_exact(model.scene)
    if exact is None:
        return None
    U = _nodal(model, sol)
    out = {}
    for b in model.bodies:
        m = b.material

        def grad(*p, piezo=m.piezoelectric):
            gu = exact.grad_u(*p)  # (..., 2, 2)
            if not piezo:
                return gu
            gp = exact.grad_phi(*p)[..., None, :]  # (..., 1, 2)
            return np.concatenate([gu, np.broadcast_to(gp, gu.shape[:-2] + (1, 2))], axis=-2)

        out[b.name] = energy_error(b.mesh, U[b.name], energy_map(m.C, m.kappa), grad)
    return out


def efficiency(eta: dict[str, np.ndarray], err2: dict[str, np.ndarray]) -> float:
    """The efficiency index (Σ η_T²)^{1/2} / (Σ ‖e‖²_T)^{1/2}."""
    num = sum(float((v**2).sum()) for v in eta.values())
    den = sum(float(v.sum()) for v in err2.values())
    return float(np.sqrt(num / den))
