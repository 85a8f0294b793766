"""A gallery of random, well-posed mixed VIs for users' tests, and hypothesis strategies.

    from vi_core.testing import random_vi, manufactured_vi, vi_strategy, manufactured_strategy

Every generator is deterministic in its integer `seed` (``np.random.default_rng(seed)``).

* `random_vi`: A = A_0 + C with A_0 symmetric positive definite of condition number `cond` and a
  skew part C scaled so that ρ = ‖A_0^{-1/2} C A_0^{-1/2}‖₂ equals `rho` (measured);
  B full row rank; Λ a product of the requested set types, its bounds sized from the
  equality-constrained multiplier so that roughly half the constraints are active.
* `manufactured_vi`: the same operators with a prescribed exact solution (u*, λ*) whose
  coordinates are inactive, active or **degenerate** (λ* on the boundary of Λ and
  B u* − gap = 0: strict complementarity fails); f = A u* + Bᵀλ*, gap = B u* − z* with
  z* ∈ N_Λ(λ*).

* `random_contact_vi`: the same operators with a product of `Free` rows and one contact block
  (`Coulomb` or `UnilateralTresca`) of k nodes in R^dim, gaps drawn so that about two thirds
  of the nodes are pressed into contact by the load and the rest lift off.

Structures: "symmetric" (C = 0), "skew-coupled" (A = [[K, Gᵀ], [−G, P]], B on the first block)
and "general" (a dense random skew C).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .constants import skew_ratio
from .coulomb import Coulomb, UnilateralTresca
from .problem import MixedVI
from .sets import Ball, Box, ConvexSet, Free, NonNegative, product

SET_TYPES = ("box", "ball", "free", "nonneg")
STRUCTURES = ("symmetric", "skew-coupled", "general")


@dataclass(frozen=True)
class Manufactured:
    """A VI with its exact solution.

    kind : per coordinate of λ (per ball coordinate, repeated within a ball):
        "free", "inactive", "active" or "degenerate".
    """

    vi: MixedVI
    u: np.ndarray  # (n,)
    lam: np.ndarray  # (m,)
    kind: np.ndarray  # (m,) of str


def _spd(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """Dense SPD matrix with eigenvalues log-spaced in [1, cond] and random eigenvectors."""
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))  # (n, n)
    eig = np.logspace(0.0, np.log10(cond), n)  # (n,)
    rng.shuffle(eig)
    M = (Q * eig) @ Q.T
    return 0.5 * (M + M.T)


def _operator(
    rng: np.random.Generator, n: int, structure: str, rho: float, cond: float
) -> tuple[np.ndarray, int]:
    """A (dense, n × n) and the number of leading columns that B may act on."""
    if structure not in STRUCTURES:
        raise ValueError(f"structure {structure!r} unknown; allowed: {', '.join(STRUCTURES)}")
    if structure == "symmetric":
        return _spd(rng, n, cond), n
    if structure == "general":
        A0 = _spd(rng, n, cond)
        R = rng.standard_normal((n, n))
        C = 0.5 * (R - R.T)  # (n, n) skew
        n_first = n
    else:
        n_first = max(n - max(n // 3, 1), 1)
        n2 = n - n_first
        if n2 < 1:
            raise ValueError("a skew-coupled operator needs n ≥ 2")
        A0 = np.zeros((n, n))
        A0[:n_first, :n_first] = _spd(rng, n_first, cond)
        A0[n_first:, n_first:] = _spd(rng, n2, cond)
        G = rng.standard_normal((n2, n_first))
        C = np.zeros((n, n))
        C[:n_first, n_first:] = G.T
        C[n_first:, :n_first] = -G
    measured = skew_ratio(sp.csr_matrix(A0), sp.csr_matrix(C))
    return A0 + (rho / measured) * C, n_first


def _layout(sets: Sequence[str], m: int, ball_dim: int) -> list[tuple[str, int]]:
    """Split m coordinates among the set types: [(type, number of coordinates)]."""
    unknown = set(sets) - set(SET_TYPES)
    if unknown or not sets:
        raise ValueError(f"sets must be a non-empty subset of {SET_TYPES}, got {tuple(sets)}")
    sets = list(dict.fromkeys(sets))
    need = sum(ball_dim if s == "ball" else 1 for s in sets)
    if m < need:
        raise ValueError(f"m = {m} is too small for the set types {tuple(sets)} (need ≥ {need})")
    share = [m // len(sets)] * len(sets)
    for i in range(m - sum(share)):
        share[i] += 1
    out = []
    spare = 0
    for s, k in zip(sets, share, strict=True):
        k += spare
        spare = 0
        if s == "ball":
            k_ball = max(k // ball_dim, 1) * ball_dim
            spare = k - k_ball
            k = k_ball
        out.append((s, k))
    others = [i for i, (s, _) in enumerate(out) if s != "ball"]
    if spare and others:  # the last block was a ball: give the rest to a non-ball block
        out[others[0]] = (out[others[0]][0], out[others[0]][1] + spare)
    return [(s, k) for s, k in out if k > 0]


def _vi(rng: np.random.Generator, spread: float, A, B, f, Lambda, gap, **info) -> tuple:
    """The MixedVI of dense A (n, n), B (m, n), f (n,) in random units u = S ũ,
    S = 10^U(−spread, spread) (1 when spread = 0), and S (n,)."""
    s = 10.0 ** rng.uniform(-spread, spread, A.shape[0]) if spread > 0 else np.ones(A.shape[0])
    A, B = sp.csr_matrix(s[:, None] * A * s[None, :]), sp.csr_matrix(B * s[None, :])
    return MixedVI(A=A, B=B, f=s * f, Lambda=Lambda, gap=gap, info=info), s


def _constraints(rng: np.random.Generator, m: int, n: int, n_first: int) -> np.ndarray:
    """B (m, n): random on the n_first leading columns (those it may act on), zero beyond."""
    if m > n_first:
        raise ValueError(f"m = {m} exceeds the {n_first} columns B may act on")
    B = np.zeros((m, n))
    B[:, :n_first] = rng.standard_normal((m, n_first))
    return B


def _operators(rng, n, m, sets, structure, rho, cond, ball_dim) -> tuple:
    """A (`_operator`), the layout of Λ (`_layout`) and B (`_constraints`)."""
    A, n_first = _operator(rng, n, structure, rho, cond)
    layout = _layout(sets, m, ball_dim)
    return A, _constraints(rng, sum(k for _, k in layout), n, n_first), layout


def random_vi(
    seed: int,
    n: int = 20,
    m: int = 8,
    sets: Sequence[str] = SET_TYPES,
    structure: str = "symmetric",
    rho: float = 0.5,
    cond: float = 10.0,
    ball_dim: int = 2,
    spread: float = 0.0,
) -> MixedVI:
    """A random well-posed MixedVI.

    n, m : sizes (m coordinates of Λ are split among `sets`; a ball block is rounded down to
        a multiple of `ball_dim`, the rest goes to another block, or is dropped).
    rho : ‖A_0^{-1/2} C A_0^{-1/2}‖₂ (ignored when symmetric).
    cond : condition number of A_0 (of K and P for skew-coupled). spread : decades of random
        variable units (u = S ũ), to exercise equilibration. The bounds of Λ are sized from
        the multiplier of the equality-constrained problem so that about half are active.
    """
    rng = np.random.default_rng(seed)
    A, B, layout = _operators(rng, n, m, sets, structure, rho, cond, ball_dim)
    m = B.shape[0]
    f = rng.standard_normal(n)
    gap = 0.5 * rng.standard_normal(m)
    # multiplier of the equality-constrained problem: sizes the bounds
    K = np.block([[A, B.T], [B, np.zeros((m, m))]])
    lam_eq = np.linalg.solve(K, np.concatenate([f, gap]))[n:]  # (m,)
    scale = np.median(np.abs(lam_eq)) + 1e-3  # typical multiplier size
    blocks: list[ConvexSet] = []
    start = 0
    for kind, k in layout:
        if kind == "free":
            blocks.append(Free(k))
        elif kind == "nonneg":
            blocks.append(NonNegative(k))
        elif kind == "box":
            hi = scale * rng.uniform(0.2, 1.0, k)
            lo = -scale * rng.uniform(0.2, 1.0, k)
            blocks.append(Box(lo, hi))
        else:
            norms = np.linalg.norm(lam_eq[start : start + k].reshape(-1, ball_dim), axis=1)
            blocks.append(Ball(norms * rng.uniform(0.3, 1.2, norms.size) + 1e-3, ball_dim))
        start += k
    info = {"gallery": "random_vi", "seed": seed, "structure": structure, "rho": rho}
    return _vi(rng, spread, A, B, f, product(*blocks), gap, **info)[0]


def manufactured_vi(
    seed: int,
    n: int = 20,
    m: int = 8,
    sets: Sequence[str] = SET_TYPES,
    structure: str = "symmetric",
    rho: float = 0.5,
    cond: float = 10.0,
    ball_dim: int = 2,
    active: float = 0.4,
    degenerate: float = 0.2,
    spread: float = 0.0,
) -> Manufactured:
    """A MixedVI with a known exact solution (u*, λ*) (see the module docstring).

    active, degenerate : probabilities that a constrained coordinate (a ball) is active
        (λ* on the boundary, strictly complementary) or degenerate (λ* on the boundary and
        (B u* − gap) = 0); otherwise it is inactive (λ* in the interior, B u* − gap = 0).
    """
    if not (0 <= active and 0 <= degenerate and active + degenerate <= 1):
        raise ValueError("need active, degenerate ≥ 0 and active + degenerate ≤ 1")
    rng = np.random.default_rng(seed)
    A, B, layout = _operators(rng, n, m, sets, structure, rho, cond, ball_dim)
    m = B.shape[0]
    u = rng.standard_normal(n)
    lam, z = np.zeros(m), np.zeros(m)  # z = B u* − gap ∈ N_Λ(λ*)
    kind = np.empty(m, dtype=object)
    blocks: list[ConvexSet] = []
    start = 0

    def draw(k: int) -> np.ndarray:
        p = np.array([max(1.0 - active - degenerate, 0.0), active, degenerate])
        return rng.choice(3, size=k, p=p / p.sum())

    for name, k in layout:
        s = slice(start, start + k)
        if name == "free":
            blocks.append(Free(k))
            lam[s] = rng.standard_normal(k)
            kind[s] = "free"
        elif name == "nonneg":
            blocks.append(NonNegative(k))
            c = draw(k)  # 0 inactive: λ > 0, z = 0; 1 active: λ = 0, z < 0; 2 degenerate
            lam[s] = np.where(c == 0, rng.uniform(0.2, 1.5, k), 0.0)
            z[s] = np.where(c == 1, -rng.uniform(0.2, 1.5, k), 0.0)
            kind[s] = np.array(["inactive", "active", "degenerate"])[c]
        elif name == "box":
            lo, hi = -rng.uniform(0.5, 1.5, k), rng.uniform(0.5, 1.5, k)
            blocks.append(Box(lo, hi))
            c = draw(k)
            upper = rng.random(k) < 0.5  # which bound is active
            bound = np.where(upper, hi, lo)  # (k,)
            lam[s] = np.where(c == 0, rng.uniform(0.1, 0.9, k) * bound, bound)
            z[s] = np.where(c == 1, np.sign(bound) * rng.uniform(0.2, 1.5, k), 0.0)
            kind[s] = np.array(["inactive", "active", "degenerate"])[c]
        else:
            nb = k // ball_dim
            radius = rng.uniform(0.5, 1.5, nb)
            blocks.append(Ball(radius, ball_dim))
            c = draw(nb)
            d = rng.standard_normal((nb, ball_dim))
            d /= np.linalg.norm(d, axis=1, keepdims=True)  # (nb, dim) unit directions
            r = np.where(c == 0, rng.uniform(0.1, 0.9, nb), 1.0) * radius  # (nb,)
            lam[s] = (d * r[:, None]).ravel()
            t = np.where(c == 1, rng.uniform(0.2, 1.5, nb), 0.0)  # (nb,)
            z[s] = (d * t[:, None]).ravel()
            kind[s] = np.repeat(np.array(["inactive", "active", "degenerate"])[c], ball_dim)
        start += k
    gap = B @ u - z
    f = A @ u + B.T @ lam
    info = {"gallery": "manufactured_vi", "seed": seed, "structure": structure, "rho": rho}
    vi, scale = _vi(rng, spread, A, B, f, product(*blocks), gap, **info)
    return Manufactured(vi=vi, u=u / scale, lam=lam, kind=kind.astype(str))


def random_contact_vi(
    seed: int,
    n: int = 20,
    k: int = 4,
    dim: int = 2,
    F: float | np.ndarray = 0.3,
    law: str = "coulomb",
    structure: str = "symmetric",
    rho: float = 0.5,
    cond: float = 10.0,
    free: int = 0,
    spread: float = 0.0,
    decoupled: bool = False,
) -> MixedVI:
    """A random contact problem: Λ = Free(free) × Coulomb(F, dim) (k nodes) or
    Free(free) × UnilateralTresca(g = F, dim, contact_only=True) (law="tresca").

    The normal gaps are set from the solution u_0 with the free rows only (A u_0 + B_freeᵀμ = f,
    B_free u_0 = gap_free): about two thirds of the nodes (at least one) get
    (B u_0)_n − gap_n > 0 (the load presses them into contact), the others lift off; tangential
    gaps are 0. F scales with the typical normal pressure: the friction radius F λ_n
    and the tangential loads are of one size for F ≈ 1.
    decoupled : A block diagonal, the free and normal rows of B acting on the first block and
        the tangential rows on the second: λ_n does not depend on friction (a bilateral-like
        pressure known in advance), and Coulomb is exactly Tresca with g = F λ_n.
    """
    if law not in ("coulomb", "tresca"):
        raise ValueError(f"law {law!r} unknown; allowed: coulomb, tresca")
    rng = np.random.default_rng(seed)
    m = free + k * dim
    normal = free + dim * np.arange(k)  # (k,) rows of the normal multipliers
    if decoupled:
        # A = diag(A_1, A_2); free and normal rows act on block 1, tangential rows on block 2
        n1 = n // 2
        A1, c1 = _operator(rng, n1, structure, rho, cond)
        A2, c2 = _operator(rng, n - n1, structure, rho, cond)
        A = np.block([[A1, np.zeros((n1, n - n1))], [np.zeros((n - n1, n1)), A2]])
        tangential = np.setdiff1d(np.arange(free, m), normal)
        if free + k > c1 or tangential.size > c2:
            raise ValueError(f"n = {n} is too small for {k} decoupled nodes in R^{dim}")
        B = np.zeros((m, n))
        rows1 = np.concatenate([np.arange(free), normal])
        B[np.ix_(rows1, np.arange(c1))] = rng.standard_normal((rows1.size, c1))
        B[np.ix_(tangential, n1 + np.arange(c2))] = rng.standard_normal((tangential.size, c2))
    else:
        A, n_first = _operator(rng, n, structure, rho, cond)
        B = _constraints(rng, m, n, n_first)
    f = rng.standard_normal(n)
    # constraint values of the solution with the free rows only (B_free u = gap_free)
    gap_free = 0.5 * rng.standard_normal(free)
    K = np.block([[A, B[:free].T], [B[:free], np.zeros((free, free))]])
    z0 = B @ np.linalg.solve(K, np.concatenate([f, gap_free]))[:n]  # (m,)
    gap = np.zeros(m)
    gap[:free] = gap_free
    size = np.median(np.abs(z0[normal])) + 1e-3
    pressed = rng.random(k) < 2.0 / 3.0
    pressed[rng.integers(k)] = True  # at least one node is pressed: some contact
    push = size * np.where(pressed, -rng.uniform(1.0, 3.0, k), rng.uniform(0.1, 0.5, k))
    gap[normal] = z0[normal] + push
    contact = Coulomb(F, dim, k=k) if law == "coulomb" else UnilateralTresca(F, dim, k=k)
    info = {"gallery": "random_contact_vi", "seed": seed, "structure": structure, "rho": rho}
    return _vi(rng, spread, A, B, f, product(Free(free), contact), gap, **info)[0]


def _params(draw, structures, sets, n_range, rho_range, cond_range):
    """Draw the common parameters of a gallery problem."""
    from hypothesis import strategies as st

    structure = draw(st.sampled_from(tuple(structures)))
    chosen = draw(st.lists(st.sampled_from(tuple(sets)), min_size=1, max_size=4, unique=True))
    ball_dim = draw(st.sampled_from((2, 3)))
    need = sum(ball_dim if s == "ball" else 1 for s in chosen)
    n = draw(st.integers(max(n_range[0], 2 * need + 2), max(n_range[1], 2 * need + 2)))
    n_first = n if structure != "skew-coupled" else n - max(n // 3, 1)
    m = draw(st.integers(need, max(need, min(n_first, n // 2))))
    return {
        "seed": draw(st.integers(0, 2**32 - 1)),
        "n": n,
        "m": m,
        "sets": tuple(chosen),
        "structure": structure,
        # ρ on a 0.1 grid: hypothesis' float draws crowd the ends of the range
        "rho": (
            draw(st.integers(round(10 * rho_range[0]), round(10 * rho_range[1]))) / 10
            if structure != "symmetric"
            else 0.0
        ),
        "cond": draw(st.floats(*cond_range)),
        "ball_dim": ball_dim,
    }


def vi_strategy(
    structures: Sequence[str] = STRUCTURES,
    sets: Sequence[str] = SET_TYPES,
    n_range: tuple[int, int] = (6, 40),
    rho_range: tuple[float, float] = (0.1, 3.0),
    cond_range: tuple[float, float] = (1.0, 100.0),
    spread: float = 0.0,
):
    """Hypothesis strategy of `random_vi` problems (a seed and parameters are drawn)."""
    return _strategy(random_vi, None, spread, structures, sets, n_range, rho_range, cond_range)


def manufactured_strategy(
    structures: Sequence[str] = STRUCTURES,
    sets: Sequence[str] = SET_TYPES,
    n_range: tuple[int, int] = (6, 40),
    rho_range: tuple[float, float] = (0.1, 3.0),
    cond_range: tuple[float, float] = (1.0, 100.0),
    degenerate: tuple[float, float] = (0.0, 0.4),
    spread: float = 0.0,
):
    """Hypothesis strategy of `manufactured_vi` problems (with their exact solutions)."""
    return _strategy(
        manufactured_vi, degenerate, spread, structures, sets, n_range, rho_range, cond_range
    )


def _strategy(build, degenerate, spread, *ranges):
    """Strategy of `build(**params, spread)`: `_params`, then (given `degenerate`) the shares."""
    from hypothesis import strategies as st

    @st.composite
    def strategy(draw):
        p = _params(draw, *ranges)
        if degenerate is not None:
            p["degenerate"] = deg = draw(st.floats(*degenerate))
            p["active"] = draw(st.floats(0.0, 1.0 - deg))
        return build(**p, spread=spread)

    return strategy()
