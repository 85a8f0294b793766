"""The shipped scene `unilateral_manufactured` (problems.scene.manufactured_unilateral): its
exact (u, λ) solves the contact problem its data pose, checked pointwise from the scene file
alone (the contact conditions on Γ3 with their zones at the chosen points, λ = −σ(u)n, the
balance and the side data by finite differences); each check fails when a sign is flipped."""

from pathlib import Path

import numpy as np
import pytest

from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from problems.scene import manufactured_unilateral as mu
from problems.scene.exact import split_exact
from problems.scene.fields import evaluate
from problems.scene.materials import isotropic_plane_strain

SCENE = Path(__file__).resolve().parents[3] / "problems" / "scenes" / "unilateral_manufactured.toml"
X = np.linspace(0.0, 2.0, 4001)  # (n,) points of Γ3 = bottom
LAM_TOL, U_TOL = 1e-6 * 1e7, 1e-9 * 1e-3  # Pa, m: rounding of the printed expressions


def _scene():
    rest, exact = split_exact(load_scene(SCENE))
    return rest.validated(pc.SCENE_MODEL), exact


def _traces() -> dict[str, np.ndarray]:
    """The fields on Γ3 (n = (0, −1), τ = (1, 0)), each (n,): normal displacement u_n = −u_2,
    slip s = u_1, gap, bound g, λ_n, λ_t from [exact] and [contact]."""
    spec, exact = _scene()
    y = np.zeros_like(X)
    u = exact.u(X, y)  # (n, 2)
    lam = exact.lam(X, y)  # (n, 2)
    return {
        "un": -u[:, 1],
        "s": u[:, 0],
        "gap": np.broadcast_to(spec.contact.gap(X, y), X.shape),
        "g": np.broadcast_to(spec.contact.g(X, y), X.shape),
        "lam_n": lam[:, 0],
        "lam_t": lam[:, 1],
    }


def violations(t: dict[str, np.ndarray]) -> list[str]:
    """The contact conditions that fail somewhere on Γ3 (unilateral contact, Tresca friction
    where it touches; λ_t s ≥ 0 is the estimator's sign of the friction law)."""
    open_ = t["gap"] - t["un"]  # (n,) the separation, ≥ 0
    touching = open_ <= U_TOL
    stick = touching & (np.abs(t["lam_t"]) < t["g"] - LAM_TOL)
    bad = {
        "λ_n ≥ 0": t["lam_n"] < -LAM_TOL,
        "gap − u_n ≥ 0": open_ < -U_TOL,
        "λ_n (gap − u_n) = 0": (t["lam_n"] > LAM_TOL) & ~touching,
        "λ_t = 0 where open": ~touching & (np.abs(t["lam_t"]) > LAM_TOL),
        "|λ_t| ≤ g": touching & (np.abs(t["lam_t"]) > t["g"] + LAM_TOL),
        "s = 0 where sticking": stick & (np.abs(t["s"]) > U_TOL),
        "λ_t s = g |s| where slipping": touching
        & (np.abs(t["s"]) > U_TOL)
        & (t["lam_t"] * t["s"] < (t["g"] - LAM_TOL) * np.abs(t["s"])),
    }
    return [name for name, where in bad.items() if where.any()]


def test_contact_conditions_hold_pointwise():
    assert violations(_traces()) == []


def test_zones_are_at_the_chosen_points():
    """Separation for x < a, stick on (a, b), slip for x > b, off the mesh nodes (a, b not
    dyadic)."""
    t = _traces()
    a, b = mu.A_CONTACT, mu.B_SLIP
    touching = t["gap"] - t["un"] <= U_TOL
    slipping = np.abs(t["s"]) > U_TOL
    near = 2e-3  # the cubic separation and slip pass the tolerances within this of a, b
    assert np.all(touching[X >= a]) and not np.any(touching[X < a - near])
    assert np.all(slipping[X > b + near]) and not np.any(slipping[X <= b])
    inner = (X > a + 0.01) & (X < b - 0.01)
    assert np.all(t["lam_n"][X > a + 0.01] > LAM_TOL) and np.all(t["lam_n"][X < a] == 0)
    assert np.all(np.abs(t["lam_t"][inner]) < t["g"][inner] - LAM_TOL)


@pytest.mark.parametrize(
    ("field", "expect"),
    [
        ("lam_n", "λ_n ≥ 0"),
        ("lam_t", "λ_t s = g |s| where slipping"),
        ("s", "λ_t s = g |s| where slipping"),
        ("open", "gap − u_n ≥ 0"),
    ],
)
def test_mutation_a_flipped_sign_is_seen(field, expect):
    """Each sign flipped in turn (λ_n, λ_t, the slip, the separation gap − u_n)."""
    t = _traces()
    if field == "open":
        t["un"] = 2 * t["gap"] - t["un"]
    else:
        t[field] = -t[field]
    assert expect in violations(t)


SHIFTS = {  # a fault per remaining condition: (field, change, the condition it breaks)
    "λ_n beyond the contact zone": ("lam_n", 1e5, "λ_n (gap − u_n) = 0"),
    "λ_t on the open part": ("lam_t", 1e5, "λ_t = 0 where open"),
    "a slip while sticking": ("s", 1e-6, "s = 0 where sticking"),
}


@pytest.mark.parametrize("fault", SHIFTS)
def test_mutation_a_shifted_field_is_seen(fault):
    """λ_n, λ_t or the slip moved by a constant, each breaks its own condition."""
    field, delta, expect = SHIFTS[fault]
    t = _traces()
    t[field] = t[field] + delta
    assert expect in violations(t)


def test_mutation_a_halved_bound_is_seen():
    t = _traces()
    t["g"] = t["g"] / 2
    assert "|λ_t| ≤ g" in violations(t)


def _stress(grad: np.ndarray, C: np.ndarray) -> np.ndarray:
    """σ (..., 2, 2) of ∇u (..., 2, 2) for the plane-strain Voigt matrix C (3, 3)."""
    eps = np.stack([grad[..., 0, 0], grad[..., 1, 1], grad[..., 0, 1] + grad[..., 1, 0]], -1)
    s = eps @ C.T  # (..., 3)
    return np.stack(
        [np.stack([s[..., 0], s[..., 2]], -1), np.stack([s[..., 2], s[..., 1]], -1)], -2
    )


def _residuals(sign: float = 1.0) -> dict[str, float]:
    """Relative residuals of the data against the exact u: λ − (−σn) on Γ3, f + Div σ (central
    differences of ∇u) at interior points, the side tractions − σn, the top displacement − u;
    `sign` multiplies the scene's body force (−1: the mutation)."""
    spec, exact = _scene()
    body = spec.bodies["block"]
    C = isotropic_plane_strain(body.material.E, body.material.nu)
    y0 = np.zeros_like(X)
    sig0 = _stress(exact.grad_u(X, y0), C)  # (n, 2, 2)
    lam = exact.lam(X, y0)
    out = {"λ": np.abs(lam - np.stack([-sig0[:, 1, 1], sig0[:, 0, 1]], -1)).max() / 1e7}
    rng = np.random.default_rng(0)
    px, py = rng.uniform(0.05, 1.95, 200), rng.uniform(0.05, 0.95, 200)
    px = px[(np.abs(px - mu.A_CONTACT) > 0.01) & (np.abs(px - mu.B_SLIP) > 0.01)]  # f jumps
    py = py[: px.size]
    d = 1e-5
    div = sum(
        (
            _stress(exact.grad_u(px + d * e[0], py + d * e[1]), C)[..., j]
            - _stress(exact.grad_u(px - d * e[0], py - d * e[1]), C)[..., j]
        )
        / (2 * d)
        for j, e in enumerate(((1, 0), (0, 1)))
    )  # (m, 2)
    f = sign * evaluate(body.body_force, px, py)
    out["balance"] = np.abs(f + div).max() / np.abs(div).max()
    ys = np.linspace(0.0, 1.0, 101)
    for part in body.traction:
        xs = np.full_like(ys, 0.0 if part.boundary == "left" else 2.0)
        n = np.array([-1.0, 0.0] if part.boundary == "left" else [1.0, 0.0])
        sn = _stress(exact.grad_u(xs, ys), C) @ n
        out[part.boundary] = np.abs(evaluate(part.value, xs, ys) - sn).max() / 1e7
    (top,) = body.displacement
    xs = np.linspace(0.0, 2.0, 101)
    ones = np.ones_like(xs)
    out["top"] = np.abs(evaluate(top.value, xs, ones) - exact.u(xs, ones)).max() / 1e-3
    return out


def test_data_are_those_of_the_exact_solution():
    res = _residuals()
    assert max(res.values()) < 1e-6, res


def test_mutation_a_flipped_body_force_is_seen():
    assert _residuals(-1.0)["balance"] > 0.5
