"""How the two bodies of a contact interface stand to each other in the reference
configuration: 2D separation along the slave normals (`check_separation`, `initial_gap`),
3D reach and facing (`reach`, `not_facing`); one tolerance SEPARATION_TOL for both."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from fem.facets import Trace, trace
from fem.mesh import Mesh
from problems.errors import SceneError

from .bodies import LEVEL0_MESHES
from .interface import SURFACE_ORDER

# Two-body interfaces must coincide in the reference configuration (bilateral contact has no
# initial gap). A slave node may sit off the master polyline (distance along its normal) by at
# most SEPARATION_TOL × h (3D: overlap it by at most SEPARATION_TOL × the level-0 node size),
# h the longest of its adjacent slave segments and the master segment
# it faces, measured on the level-0 mesh (h · 2^level: uniform refinement does not change the
# geometry of a mesh read from a file, whose new boundary nodes stay on its polylines): this
# admits the chord-versus-arc discrepancy of a discretised curved interface (the sagitta
# h²/(8r), i.e. h/(8r) relative to h: 0.02 for the paper's mesh, < 0.1 while h < 0.8 r), e.g.
# two bodies meshed separately in gmsh along one curve, and refuses bodies that overlap or
# stand apart by more (docs/design.md, "Meshes from files").
SEPARATION_TOL = 0.1


def normal_distances(
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


def to_master(
    x: np.ndarray, n: np.ndarray, master: Any, mpart: str
) -> tuple[np.ndarray, np.ndarray, Trace]:
    """(t, k, mtr): the signed distance t (M,) from each point x (M, 2) along its normal n
    (M, 2) to the master body's boundary part `mpart` (NaN where it misses:
    `normal_distances`), the master segment k (M,) hit, and the master trace mtr."""
    mtr = trace(master.mesh, mpart)
    P = master.mesh.points[mtr.nodes]  # (n_m, 2)
    t, k = normal_distances(x, n, P[mtr.facets[:, 0]], P[mtr.facets[:, 1]])
    return t, k, mtr


def separation(slave: Any, part: str, tr: Trace, normals, master: Any, mpart: str, level: int):
    """(t, h): the signed distance (N,) of each slave node along its normal to the master
    polyline (NaN where it misses) and h (N,), the longer of the node's adjacent segments and
    the master segment hit, times 2^level (the level-0 mesh size). Bodies built on locally
    refined meshes (`bodies.given_meshes` with their level-0 meshes) have no uniform level: h is
    then measured on the level-0 meshes (`level0_sizes`)."""
    x = slave.mesh.points[tr.nodes]  # (N, 2)
    t, k, mtr = to_master(x, normals, master, mpart)
    level0 = LEVEL0_MESHES.get() or {}
    if slave.name in level0 and master.name in level0:
        return t, level0_sizes(x, normals, level0[slave.name], part, level0[master.name], mpart)
    h = mtr.measures[k]
    np.maximum.at(h, tr.facets[:, 0], tr.measures)
    np.maximum.at(h, tr.facets[:, 1], tr.measures)
    return t, h * 2.0**level  # the size at level 0, where the interface geometry was given


def level0_sizes(
    x: np.ndarray, n: np.ndarray, slave0: Mesh, part: str, master0: Mesh, mpart: str
) -> np.ndarray:
    """The level-0 mesh size (N,) at slave nodes x (N, 2) with normals n (N, 2) of a locally
    refined slave body: the longer of the level-0 slave segment(s) nearest to the node (both of
    a level-0 node) and the level-0 master segment its normal hits (`normal_distances`);
    slave0, master0 the level-0 meshes."""
    s0 = trace(slave0, part)
    P = slave0.points[s0.nodes]  # (n_0, 2)
    a, b = P[s0.facets[:, 0]], P[s0.facets[:, 1]]  # (M, 2) each
    d = b - a  # (M, 2)
    h = np.empty(len(x))
    for lo in range(0, len(x), 256):
        xi = x[lo : lo + 256, None, :]  # (c, 1, 2)
        s = np.clip(((xi - a) * d).sum(-1) / (d * d).sum(-1), 0.0, 1.0)  # (c, M)
        dist = np.linalg.norm(xi - (a + s[..., None] * d), axis=2)  # (c, M)
        near = dist <= dist.min(axis=1, keepdims=True) + 1e-9 * s0.measures  # (c, M)
        h[lo : lo + 256] = np.where(near, s0.measures, 0.0).max(axis=1)
    m0 = trace(master0, mpart)
    Q = master0.points[m0.nodes]  # (n_m0, 2)
    _, k = normal_distances(x, n, Q[m0.facets[:, 0]], Q[m0.facets[:, 1]])
    return np.maximum(h, m0.measures[k])


def _refuse(slave, part, master, mpart, tr, t, h, bad, where) -> None:
    rel = np.nan_to_num(t / h)
    i = bad[np.argmax(np.abs(rel[bad]))]
    what = "overlap the slave body" if rel[i] < 0 else "stand apart from it"
    raise SceneError(
        "contact.master",
        f"{master.name}.{mpart}",
        f"a master boundary {where} {slave.name}.{part} in the "
        f"reference configuration: it would {what} by {abs(t[i]):.3g} "
        f"({abs(rel[i]):.2f} × the local level-0 mesh size {h[i]:.3g}; allowed "
        f"{SEPARATION_TOL:g}) at slave node {slave.mesh.points[tr.nodes[i]].tolist()}",
    )


def check_separation(
    slave: Any, part: str, tr: Trace, normals, master: Any, mpart: str, level: int = 0
) -> float:
    """SceneError if the interfaces overlap or stand apart by more than SEPARATION_TOL·h
    (`separation`): bilateral contact needs coincident interfaces. Returns the largest gap
    (m, ≥ 0) between them that bilateral contact closes (`closed_gap_warning`)."""
    t, h = separation(slave, part, tr, normals, master, mpart, level)
    bad = np.flatnonzero(np.abs(np.nan_to_num(t / h)) > SEPARATION_TOL)
    if bad.size:
        _refuse(slave, part, master, mpart, tr, t, h, bad, "that coincides with")
    return float(np.maximum(np.nan_to_num(t), 0.0).max(initial=0.0))


def initial_gap(
    slave: Any, part: str, tr: Trace, normals, master: Any, mpart: str, level: int = 0
) -> np.ndarray:
    """The initial normal gap (N,) of unilateral contact between two bodies: the distance
    along each slave normal to the master (0 where the normal misses it). The bodies may
    start apart; an overlap beyond SEPARATION_TOL·h (`separation`) is refused."""
    t, h = separation(slave, part, tr, normals, master, mpart, level)
    bad = np.flatnonzero(-np.nan_to_num(t / h) > SEPARATION_TOL)
    if bad.size:
        _refuse(slave, part, master, mpart, tr, t, h, bad, "facing")
    return np.nan_to_num(t)


def reach(slave: Any, part: str, master: Any, mpart: str) -> float:
    """How far the master surface stands from the slave one, in slave face sizes: the largest
    distance of a slave surface node to the nearest master surface node over the smallest
    slave face diameter (0 for coincident surfaces); it widens the mortar's candidate search
    for bodies that start apart."""
    faces = slave.mesh.boundaries[part]  # (n_f, k)
    P = slave.mesh.points
    xs = P[np.unique(faces)]
    xm = master.mesh.points[np.unique(master.mesh.boundaries[mpart])]
    d, _ = cKDTree(xm).query(xs)
    size = np.linalg.norm(P[faces[:, 0]] - P[faces[:, 2]], axis=1).min()  # a diagonal
    return float(d.max() / size)


def not_facing(surf: Trace, master: Any) -> str:
    """What is wrong with a master surface that lies behind no slave node's support (what a
    master must be, and which of the three ways it is not: it faces the same way as the slave,
    it lies behind the slave, or the two do not overlap seen along the slave's normal)."""
    mesh = master.body.mesh
    msurf = trace(mesh, master.part, SURFACE_ORDER[mesh.cell_type])
    n_s, n_m = surf.normals.mean(axis=0), msurf.normals.mean(axis=0)  # (3,) mean outward normals
    ahead = float((msurf.points.mean(axis=0) - surf.points.mean(axis=0)) @ n_s)
    if float(n_s @ n_m) > 0:
        why = "the two surfaces face the same way (their outward normals agree)"
    elif ahead < 0:
        why = "the two surfaces face away from each other (the master lies behind the slave)"
    else:
        why = "the two surfaces do not overlap seen along the slave's normal"
    return (
        "a master surface facing the slave one and overlapping it: no slave node has this master "
        f"behind its faces, so no contact multiplier can be placed; {why}"
    )
