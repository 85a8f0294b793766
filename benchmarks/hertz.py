"""Hertz line contact measured on a solved contact model: the load P, the contact half-width
and the peak pressure, against the closed form (`problems.scene.contact_references`).

Half-width by the second moment of the pressure: for Hertz's p = p0 sqrt(1 − x²/a²),
∫x²p / ∫p = a²/4, so a_h = 2 (Σ w_i λ_i x_i² / Σ w_i λ_i)^{1/2} (nodal quadrature of the
dual-mortar pressure, w_i = ∫φ_i); it uses every node, where the last touching node only
brackets a within one segment. Peak pressure: λ_n at the node nearest x = 0. The cylinder's
axis is at x = 0 and the surface normal along y.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from problems.scene.contact_references import hertz_line_contact, hertz_modulus


@dataclass(frozen=True)
class LineContact:
    """A measured line contact and its Hertz reference at the measured load."""

    P: float  # N/m, Σ w_i λ_i
    a: float  # m, second-moment half-width
    a_nodes: float  # m, |x| of the outermost touching node
    p0: float  # Pa, λ_n at x = 0
    a_ref: float
    p0_ref: float
    E_star: float

    @property
    def errors(self) -> dict[str, float]:
        """Relative errors of the half-width and the peak pressure."""
        return {"a": self.a / self.a_ref - 1.0, "p0": self.p0 / self.p0_ref - 1.0}

    def record(self) -> dict:
        """JSON-able record."""
        return {**asdict(self), "errors": self.errors}


def measure(
    x: np.ndarray, w: np.ndarray, lam_n: np.ndarray, R: float, E_star: float, touch: np.ndarray
) -> LineContact:
    """The line contact of nodal pressures lam_n (N,) at abscissae x (N,), weights w (N,);
    `touch` (N,) the nodes in contact (the plug-in's states, `vi_core.states`), whose farthest
    gives `a_nodes`."""
    P = float(w @ lam_n)
    if P <= 0 or not np.any(touch):
        raise ValueError("no contact force: nothing touches")
    a = 2.0 * float(np.sqrt((w * lam_n * x**2).sum() / P))
    ref = hertz_line_contact(P, R, E_star)
    return LineContact(
        P=P,
        a=a,
        a_nodes=float(np.abs(x[touch]).max()),
        p0=float(lam_n[np.argmin(np.abs(x))]),
        a_ref=ref.a,
        p0_ref=ref.p0,
        E_star=E_star,
    )


def of_model(model, sol, R: float) -> LineContact:
    """`measure` on a solved signorini or 2D contact (rigid foundation) model, with the
    contact body's E* from the Barnett–Lothe tensor (`hertz_modulus`): the charge-free surface
    for a piezoelectric body (insulating, or no [contact.electrical]), the conducting indenter
    for `grounded` (φ = φ_F where it touches); a `conductive` law (finite k) has no closed form
    (ValueError)."""
    kind = getattr(getattr(model, "electrical", None), "law", None)
    kind = "none" if kind is None else kind.kind
    if kind not in ("none", "grounded"):
        raise ValueError(
            f"electrical contact law {kind!r}: no Hertz reference (insulating or grounded only)"
        )
    c = getattr(model, "contact", None)
    if c is None:
        raise ValueError("no contact interface: no Hertz reference")
    # the normal rows where they sit in λ, their weights ∫φ̃_k, the touching nodes
    body, nodes, w, lam_n = c.slave, c.tr.nodes[c.rows_n], c.W_n[c.rows_n], c.normal(sol.lam)
    touch = model.contact_state(sol)["touch"]
    mat = body.material
    x = body.mesh.points[nodes, 0]
    E_star = hertz_modulus(mat.C, mat.e, mat.kappa, conducting=kind == "grounded")
    return measure(x, w, lam_n, R, E_star, touch)
