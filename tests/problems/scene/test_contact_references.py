"""Closed-form contact references: Hertz line contact and the (extended) Barnett–Lothe tensor
behind its effective modulus, each checked against an independent computation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from problems.scene import contact_references as cr
from problems.scene.materials import NAMED, isotropic_plane_strain


def _stroh_eigen_L(C, e=None, kappa=None):
    """L = −2i B Bᵀ from the Stroh eigenvectors (Ting §5.5), normalised 2 aᵀb = 1: an
    independent route to the tensor the module computes by its integral form (non-degenerate
    materials only)."""
    E = cr.extended_moduli(C, e, kappa)
    Q, R, T = E[0, :, :, 0], E[0, :, :, 1], E[1, :, :, 1]
    Ti = np.linalg.inv(T)
    N = np.block([[-Ti @ R.T, Ti], [R @ Ti @ R.T - Q, -R @ Ti]])
    p, xi = np.linalg.eig(N)
    n = Q.shape[0]
    up = np.argsort(-p.imag)[:n]
    a, b = xi[:n, up], xi[n:, up]
    b = b / np.sqrt(2.0 * np.einsum("ja,ja->a", a, b))[None, :]
    L = -2j * b @ b.T
    assert np.abs(L.imag).max() <= 1e-6 * np.abs(L.real).max()
    return L.real


GAUSS = np.polynomial.legendre.leggauss(400)


def _piezo(name, scale=1.0):
    m = NAMED[name]
    return np.array(m["C"]), scale * np.array(m["e"]), np.array(m["kappa"])


@given(E=st.floats(1e6, 1e12), nu=st.floats(-0.9, 0.49))
def test_isotropic_L_is_half_the_plane_strain_modulus(E, nu):
    L = cr.barnett_lothe_L(isotropic_plane_strain(E, nu))
    E_star = cr.isotropic_plane_strain_modulus(E, nu)
    assert np.allclose(L, 0.5 * E_star * np.eye(2), rtol=1e-12, atol=1e-12 * E_star)
    assert cr.hertz_modulus(isotropic_plane_strain(E, nu)) == pytest.approx(E_star, rel=1e-12)


@pytest.mark.parametrize("name", ["BaTiO3", "BaTiO3-Berlincourt", "PZT-5H"])
@pytest.mark.parametrize("electric", [False, True])
def test_integral_and_eigenvector_forms_agree(name, electric):
    C, e, k = _piezo(name)
    args = (C, e, k) if electric else (C,)
    L = cr.barnett_lothe_L(*args)
    assert np.allclose(L, _stroh_eigen_L(*args), rtol=1e-9, atol=1e-9 * np.abs(L).max())


def _perturbed_batio3(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """BaTiO3's (C, e, κ) with each modulus scaled by a factor drawn in [0.7, 1.3] (C kept
    symmetric, κ diagonal)."""
    rng = np.random.default_rng(seed)
    C, e, k = _piezo("BaTiO3")
    C = C * rng.uniform(0.7, 1.3, (3, 3))
    e = e * rng.uniform(0.7, 1.3, e.shape)
    return 0.5 * (C + C.T), e, np.diag(np.diag(k) * rng.uniform(0.7, 1.3, 2))


@given(seed=st.integers(0, 2**31))
def test_integral_form_on_drawn_transversely_isotropic_piezo_materials(seed):
    """Random perturbations of BaTiO3 (moduli ×[0.7, 1.3]): the two routes agree."""
    C, e, k = _perturbed_batio3(seed)
    L = cr.barnett_lothe_L(C, e, k)
    assert np.allclose(L, _stroh_eigen_L(C, e, k), rtol=1e-8, atol=1e-8 * np.abs(L).max())


def test_piezo_modulus_tends_to_the_elastic_one_and_stiffens():
    """e → 0 gives the anisotropic elastic E*; the charge-free surface of BaTiO3 is stiffer
    (Giannakopoulos & Suresh 1999 found the same for axisymmetric indentation)."""
    C, e, k = _piezo("BaTiO3")
    elastic = cr.hertz_modulus(C)
    assert cr.hertz_modulus(C, 1e-6 * e, k) == pytest.approx(elastic, rel=1e-9)
    assert cr.hertz_modulus(C, e, k) > 1.1 * elastic


@given(
    P=st.floats(1e-3, 1e9), R=st.floats(1e-3, 1e3), E=st.floats(1e6, 1e12), t=st.floats(-0.9, 0.9)
)
def test_hertz_pressure_fits_the_cylinder(P, R, E, t):
    """The elliptic pressure carries P, and the surface slope it makes on the half-plane,
    u_y'(x) = (L⁻¹)_yy/π · PV∫p(s)/(s − x) ds with (L⁻¹)_yy = 2/E*, is the cylinder's −x/R
    inside the contact (the principal value by subtracting the singularity, Gauss–Legendre)."""
    h = cr.hertz_line_contact(P, R, E)
    s, w = h.a * GAUSS[0], h.a * GAUSS[1]  # (400,) on [−a, a]
    assert w @ h.pressure(s) == pytest.approx(P, rel=1e-5)
    x = t * h.a
    px = h.pressure(np.array([x]))[0]
    pv = w @ ((h.pressure(s) - px) / (s - x)) + px * np.log((h.a - x) / (h.a + x))
    slope = (2.0 / E) / np.pi * pv
    assert slope == pytest.approx(-x / R, rel=1e-3, abs=1e-4 * h.a / R)
    assert h.pressure(np.array([1.5 * h.a]))[0] == 0.0


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="P, R, E"):
        cr.hertz_line_contact(-1.0, 1.0, 1.0)


def test_a_focus_outside_the_rectangle_is_refused():
    from problems.errors import SceneError
    from problems.plugins.signorini import SCENE_MODEL
    from problems.scene import load_scene

    with pytest.raises(SceneError, match="body.geometry.focus"):
        load_scene("hertz", ["body.geometry.focus=[0.0, 2.0]"]).validated(SCENE_MODEL)
    with pytest.raises(SceneError, match="grading"):
        load_scene("hertz", ["body.geometry.grading=[0.5, 1.0]"]).validated(SCENE_MODEL)


@given(seed=st.integers(0, 2**31))
def test_conducting_indenter_modulus_is_one_over_L_yy_and_below_the_insulating(seed):
    """Drawn perturbations of BaTiO3: the Schur-complement form equals 2 L_yy (the two routes
    agree through L⁻¹), lies between the elastic and the charge-free moduli here, and the
    insulating one is never below it (2/(L⁻¹)_yy = 2(L_yy + L_yφ²/|L_φφ|), L_φφ < 0)."""
    C, e, k = _perturbed_batio3(seed)
    L = cr.barnett_lothe_L(C, e, k)
    conducting = cr.hertz_modulus(C, e, k, conducting=True)
    assert conducting == pytest.approx(2 * L[1, 1], rel=1e-10)
    assert cr.hertz_modulus(C, e, k) > conducting
    assert cr.hertz_modulus(C, 1e-6 * e, k, conducting=True) == pytest.approx(
        cr.hertz_modulus(C), rel=1e-9
    )


def test_conducting_indenter_needs_the_mirror_symmetry():
    C, e, k = _piezo("BaTiO3")
    tilted = e.copy()
    tilted[0, 0] = 0.3 * e[1, 1]  # e_x,xx ≠ 0: no longer symmetric under x → −x
    with pytest.raises(ValueError, match="x → −x"):
        cr.hertz_modulus(C, tilted, k, conducting=True)


@given(
    delta=st.floats(-3e-6, 3e-6),
    V=st.floats(-500.0, 500.0),
    phi_F=st.floats(-1000.0, 1000.0),
    k0=st.floats(1e-8, 1e-4),
    law=st.sampled_from(["saturated", "power"]),
)
def test_two_layers_tend_to_the_foundation(delta, V, phi_F, k0, law):
    """A master layer 1e6 times stiffer and more permittive, without coupling, at V_m = φ_F:
    the two-layer state is the one-layer state on a conductive foundation at φ_F within the
    master's relative compliance 1e-6 (an independent route: one scalar equation against the
    3 × 3 system)."""
    c, e, k = (_piezo("BaTiO3")[i][1, 1] for i in range(3))
    H, lam_star = 1e-2, 2e7

    def kf(lam):
        lam = max(lam, 0.0)
        if law == "saturated":
            return k0 * min(lam / lam_star, 1.0)
        return k0 * (lam / lam_star) ** 2

    one = cr.uniaxial_electrical_contact(c, e, k, H, delta, V, phi_F, kf)
    two = cr.two_layer_electrical_contact(
        cr.Layer(c, e, k, H), cr.Layer(1e6 * c, 0.0, 1e6 * k, H), delta, V, phi_F, kf
    )
    # the potentials' scale includes the layer's piezoelectric one, e δ/κ (3,000 V at 2 μm)
    scale = max(abs(one.phi0), abs(phi_F), abs(V), abs(e * delta / k), 1.0)
    assert two.phi_s == pytest.approx(one.phi0, abs=1e-5 * scale)
    assert two.phi_m == pytest.approx(phi_F, abs=1e-5 * scale)
    assert two.lam_n == pytest.approx(one.lam_n, rel=1e-5, abs=1e-5 * (c * 1e-6 + e * scale) / H)
