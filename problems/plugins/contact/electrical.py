"""Electrical contact conditions of a piezoelectric body on its contact boundary Γ3
(docs/electrical_contact.md): the law, its boundary assembly and the outer fixed point.

Three conditions, the `[contact.electrical]` table of a contact scene (`kind`):

- "insulating": D·n = 0 on Γ3 — the natural condition of the weak form, nothing assembled.
- "conductive": a foundation at potential φ_F through a contact conductance,
  D·n = k(λ_n)(φ − φ_F), k = 0 where the body is apart (λ_n ≤ 0) and growing with the contact
  pressure λ_n (a regularised electrical contact condition: Lerguet, Shillor & Sofonea, EJDE
  2007/170; Barboteu, Fernández & Ouafik, ESAIM M2AN 42 (2008); there k depends on the normal
  displacement through a normal compliance, here on the pressure, the multiplier of the
  unilateral/bilateral constraint). Two laws, k0 ≥ 0 in F/m², λ* > 0 in Pa:
      "saturated": k(λ_n) = k0 · min(λ_n⁺, λ*) / λ*     (bounded, Lipschitz with k0/λ*)
      "power":     k(λ_n) = k0 · (λ_n⁺ / λ*)^p          (p > 0; k0 = k at λ_n = λ*)
- "grounded": an electrode at φ_F on the foundation acting only where the body touches
  (λ_n > TOUCH · max λ_n): the limit k → ∞, imposed as a penalty k = K on the touching nodes,
  K = penalty · κ_max / h (κ_max the largest permittivity of the body, h the largest segment of
  Γ3): φ − φ_F = D·n / K on the touching nodes, ~1/penalty of the potential scale.

Discretisation: with D·n = k(φ − φ_F) the electric equation gains ∫_Γ3 k (φ − φ_F) ψ ds,
assembled by the nodal (trapezoidal) rule: the diagonal matrix diag(w_i k_i) on the potential
unknowns of the trace nodes (w_i = ∫φ_i ds, k_i = k(λ_n,i)) and the load w_i k_i φ_F
(`conductance_matrix`). A + diag(w k) keeps A + Aᵀ positive definite (k ≥ 0).

Solution: the coupling is nonlinear (k depends on λ_n), solved by an outer fixed point on the
nodal k (`solve_coupled`): k⁰ = 0 (insulating), then each step solves the MixedVI with the
frozen k^j (any vi_core method, warm-started), and k^{j+1} = k(λ_n^{j+1}); it stops when
‖k^{j+1} − k^j‖_∞ ≤ tol · k_scale (k_scale = k0 or K) with the inner solve converged, and
reports the iterations, the history of ‖Δk‖_∞ and the measured contraction. After max_iter
steps it returns the last iterate marked "not converged" (Solution.converged False).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import scipy.sparse as sp
from pydantic import Field

import vi_core
from problems.scene import Section
from problems.scene.fields import Integer, Number
from vi_core import MixedVI, Solution

KINDS = ("insulating", "conductive", "grounded")
LAWS = ("saturated", "power")
# the grounded law's switch, part of the model (like vi_core.coulomb.OPEN): the electrode acts
# where λ_n > TOUCH · max λ_n (rounding of 0 is not). Reported contact states follow from the
# answer instead (vi_core.states: `touching` takes them).
TOUCH = 1e-9


class ElectricalSection(Section):
    """[contact.electrical]: the electrical condition on Γ3 (module docstring)."""

    kind: Literal[KINDS] = Field(
        "insulating",
        description="insulating: D·n = 0; conductive: D·n = k(λ_n)(φ − φ_F); grounded: φ = φ_F "
        "where the body touches (the limit k → ∞, a penalty)",
    )
    phi_F: Number = Field(0.0, description="the foundation's potential φ_F (V)")
    law: Literal[LAWS] = Field(
        "saturated",
        description="conductive: k = k0·min(λ_n⁺/λ*, 1) (saturated) or k0·(λ_n⁺/λ*)^p (power)",
    )
    k0: Annotated[Number, Field(ge=0.0, description="contact conductance scale k0 (F/m²)")] = 0.0
    lambda_star: Annotated[
        Number, Field(gt=0.0, description="pressure λ* at which k reaches k0 (Pa)")
    ] = 1.0
    p: Annotated[Number, Field(gt=0.0, le=10.0, description="exponent of the power law")] = 1.0
    penalty: Annotated[
        Number,
        Field(gt=0.0, le=1e12, description="grounded: k = penalty · κ_max / h on touching nodes"),
    ] = 1e8
    max_iter: Annotated[
        Integer, Field(ge=1, le=1000, description="outer fixed-point steps at most")
    ] = 50
    tol: Annotated[
        Number, Field(gt=0.0, lt=1.0, description="fixed point: stop at ‖Δk‖_∞ ≤ tol · k0 (or K)")
    ] = 1e-10

    def law_of(self, kappa_max: float = 1.0, h: float = 1.0) -> Law:
        """The compiled law (grounded: K = penalty · kappa_max / h)."""
        if self.kind == "grounded":
            return Law("grounded", self.penalty * kappa_max / h, 1.0, 1.0)
        kind = self.law if self.kind == "conductive" else "none"
        return Law(kind, self.k0, self.lambda_star, self.p)


@dataclass(frozen=True)
class Law:
    """k(λ_n) ≥ 0 per node: "saturated", "power", "grounded" (k0 = K) or "none" (k = 0)."""

    kind: str
    k0: float
    lambda_star: float
    p: float

    @property
    def scale(self) -> float:
        """The size of k that the fixed point's tolerance is relative to."""
        return self.k0

    def __call__(self, lam_n: np.ndarray) -> np.ndarray:
        """k (N,) at the nodal pressures lam_n (N,); 0 where lam_n ≤ 0."""
        lam = np.maximum(np.asarray(lam_n, dtype=float), 0.0)  # (N,) λ_n⁺
        if self.kind == "saturated":
            return self.k0 * np.minimum(lam / self.lambda_star, 1.0)
        if self.kind == "power":
            return self.k0 * (lam / self.lambda_star) ** self.p
        if self.kind == "grounded":
            top = float(lam.max(initial=0.0))
            return np.where(lam > TOUCH * top, self.k0, 0.0) if top > 0 else np.zeros(lam.size)
        if self.kind == "none":
            return np.zeros(lam.size)
        allowed = ", ".join((*LAWS, "grounded", "none"))
        raise ValueError(f"law {self.kind!r} unknown; allowed: {allowed}")


def conductance_matrix(weights: np.ndarray, k: np.ndarray) -> sp.dia_matrix:
    """diag(w_i k_i) (N, N): ∫_Γ3 k φ_i φ_j ds by the nodal rule (w_i = ∫φ_i ds, k_i ≥ 0)."""
    w, k = np.asarray(weights, float), np.asarray(k, float)
    if w.shape != k.shape:
        raise ValueError(f"weights {w.shape} and k {k.shape} differ in shape")
    if (k < 0).any():
        raise ValueError(f"a conductance k ≥ 0 at every node (min {k.min():.3g})")
    return sp.diags(w * k)


@dataclass
class Coupling:
    """What the fixed point needs from a built model: the VI with k = 0 (A0), where the trace
    nodes' potentials and normal multipliers sit, and the law.

    The potential jump at slave node i is [φ]_i = φ_s,i − (Π φ_m)_i − φ_F: a rigid foundation
    (or a master body without potential, a conductor) at φ_F has no Π; a piezoelectric master
    body has φ_F = 0 and Π its dual-mortar mean Σ_j M_ij φ_m,j / W_i (`master` on the unknowns,
    `fixed` the part of the jump from prescribed potentials, slave and master)."""

    vi0: MixedVI  # the insulating problem
    phi: np.ndarray  # (N,) unknown index of φ at each trace node carrying a λ_n, −1 if prescribed
    normal: np.ndarray  # (N,) index into λ of that node's normal multiplier
    weights: np.ndarray  # (N,) ∫φ_i ds
    law: Law
    phi_F: float
    max_iter: int = 50
    tol: float = 1e-10
    master: sp.csr_matrix | None = None  # (N, n) Π on the master's potential unknowns
    fixed: np.ndarray | None = None  # (N,) φ_s,i − (Πφ_m)_i of the prescribed potentials

    @property
    def jump_matrix(self) -> sp.csr_matrix:
        """G (N, n): the potential jump [φ] = G u + fixed − φ_F on the unknowns u."""
        keep = np.flatnonzero(self.phi >= 0)
        N, n = self.phi.size, self.vi0.n
        G = sp.csr_matrix((np.ones(keep.size), (keep, self.phi[keep])), shape=(N, n))
        return G if self.master is None else (G - self.master).tocsr()

    def jump(self, u: np.ndarray) -> np.ndarray:
        """[φ] (N,) at the slave nodes (NaN where the slave potential is prescribed)."""
        out = self.jump_matrix @ u - self.phi_F
        if self.fixed is not None:
            out = out + self.fixed
        return np.where(self.phi >= 0, out, np.nan)

    def frozen(self, k: np.ndarray) -> MixedVI:
        """The MixedVI with the frozen nodal conductances k (N,): + Gᵀ diag(w k) G on A and
        − Gᵀ diag(w k)(fixed − φ_F) on f (∫_Γ3 k [φ][ψ] ds by the nodal rule; a slave node
        with prescribed φ has no row: nothing flows through it)."""
        keep = self.phi >= 0
        wk = np.where(keep, self.weights * k, 0.0)  # (N,)
        G = self.jump_matrix
        const = -self.phi_F + (0.0 if self.fixed is None else self.fixed)  # (N,) or scalar
        A = self.vi0.A + self.vi0.rows_of(G.T @ sp.diags(wk) @ G)  # the rows held here
        f = self.vi0.f - G.T @ (wk * const)  # (n,)
        return dataclasses.replace(self.vi0, A=A.tocsr(), f=f)

    def conductances(self, lam: np.ndarray) -> np.ndarray:
        """k (N,) from the multipliers λ of the VI."""
        return self.law(lam[self.normal])

    def flux(self, u: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The discrete normal electric displacement D·n (N,) at the trace nodes, recovered
        from the insulating equations: (f0 − A0 u − B0ᵀλ)_φi / w_i (NaN where φ is
        prescribed) — independent of the k the solver used."""
        r = self.vi0.f - self.vi0.matvec(u) - self.vi0.B.T @ lam  # (n,)
        out = np.full(self.phi.size, np.nan)
        keep = self.phi >= 0
        out[keep] = r[self.phi[keep]] / self.weights[keep]
        return out


def solve_coupled(
    c: Coupling,
    inner: Callable[..., Solution] | None = None,
    **options,
) -> tuple[Solution, MixedVI]:
    """The outer fixed point k^{j+1} = k(λ_n(k^j)) from k⁰ = 0 (module docstring).

    inner(vi, **kw) solves one frozen problem (default `vi_core.solve` with `options`); each
    step after the first is warm-started from the last (u0, lam0 for ssn). Returns the last
    inner solution (its `converged` False unless the fixed point and the inner solve both
    converged; `info["electrical"]` the record) and the last frozen VI.
    """
    t0 = time.perf_counter()
    inner = inner or vi_core.solve
    k = np.zeros(c.phi.size)
    steps, warm, inner_iters = [], {}, []
    sol, vi = None, None
    converged = False
    scale = max(c.law.scale, 1e-300)
    for _ in range(c.max_iter):
        vi = c.frozen(k)
        sol = inner(vi, **{**options, **warm})
        inner_iters.append(sol.iterations)
        k_new = c.conductances(sol.lam)
        dk = float(np.abs(k_new - k).max(initial=0.0))
        steps.append(dk)
        k = k_new
        if not sol.converged:
            break
        if dk <= c.tol * scale:
            converged = True
            break
        if options.get("method", "ssn") in ("ssn", "auto"):
            warm = {"u0": sol.u, "lam0": sol.lam}
    c.vi0.matvec(sol.u)  # A0 u at the answer on every process (kept: `report` reads it)
    ratios = [b / a for a, b in zip(steps[:-1], steps[1:], strict=True) if a > 0]
    record = {
        "kind": c.law.kind,
        "iterations": len(steps),
        "converged": converged,
        "delta_k": steps,
        "contraction": max(ratios[-3:]) if ratios else None,
        "inner_iterations": inner_iters,
        "k_scale": c.law.scale,
        "time_s": time.perf_counter() - t0,
    }
    # "outer": what the commands print of any outer iteration around the VI
    outer = {"what": "electrical contact fixed point on k", "iterations": len(steps)}
    info = {**sol.info, "electrical": record, "outer": outer}
    warnings = list(sol.warnings)
    if not converged:
        why = "the inner solve did not converge" if not sol.converged else f"‖Δk‖ = {steps[-1]:.3g}"
        warnings.append(
            f"electrical contact: fixed point not converged after {len(steps)} step(s) ({why}, "
            f"tolerance {c.tol:g} × {scale:.3g})"
        )
    out = dataclasses.replace(
        sol,
        converged=bool(converged and sol.converged),
        iterations=int(sum(inner_iters)),
        time=time.perf_counter() - t0,
        info=info,
        warnings=warnings,
    )
    return out, vi


def report(c: Coupling, sol: Solution) -> dict:
    """summary.json["electrical"]: the condition, the fixed point's record and the law checked
    at the answer with D·n recovered from the insulating equations (`Coupling.flux`):
    law_defect = max_i |D·n_i − k(λ_n,i)(φ_i − φ_F)| / max(max_i |D·n_i|, tiny)."""
    lam_n = sol.lam[c.normal]
    jump = c.jump(sol.u)  # (N,) φ_s − Πφ_m − φ_F, NaN where φ_s is prescribed
    flux = c.flux(sol.u, sol.lam)  # (N,)
    law = c.law(lam_n) * jump
    top = float(np.nanmax(np.abs(flux), initial=0.0))
    defect = float(np.nanmax(np.abs(flux - law), initial=0.0)) / max(top, 1e-300)
    return {
        "kind": c.law.kind,
        "phi_F": c.phi_F,
        "k_scale": c.law.scale,
        "flux_max": top,
        "law_defect": defect if top > 0 else float(np.nanmax(np.abs(law), initial=0.0)),
        "fixed_point": sol.info.get("electrical"),
    }


def touching(c: Coupling, sol: Solution, touch: np.ndarray) -> dict:
    """summary.json["electrical"]'s entries on the touching nodes `touch` (N,) — the contact
    states of the answer (`vi_core.states`, the plug-in's `contact_state`), not the law's
    switch TOUCH: their count and, where their potential is unknown, the largest potential
    gap |φ_s − Πφ_m − φ_F| (grounded: the penalty's accuracy)."""
    touch = np.asarray(touch, dtype=bool)
    out: dict = {"touching_nodes": int(touch.sum())}
    keep = c.phi >= 0
    if touch.any() and keep[touch].any():
        out["potential_gap_touching"] = float(np.nanmax(np.abs(c.jump(sol.u)[touch])))
    return out
