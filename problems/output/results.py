"""Results as data: the contact table (contact.csv, contact.vtu, summary entries), named VTU
tensors, von Mises, and the .pvd collection — the files a ParaView or pandas user reads.

Conventions (docs/design.md, "Results"): lengths in m, multipliers (contact tractions) in Pa,
forces per unit thickness in N/m. The multiplier λ = λ_n n + λ_t τ enters the equations as
A u + Bᵀλ = f, so the traction the other side exerts on the slave body is −λ; for the
bilateral contact of piezo_contact λ_n > 0 is compression, and for unilateral contact
(signorini) the pressure is λ_n ≥ 0 as well. τ = (−n_y, n_x): n turned counterclockwise by 90°.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

STATES = ("stick", "slip", "open", "no_multiplier")
UNITS = {
    "x": "m",
    "y": "m",
    "normal_x": "1",
    "normal_y": "1",
    "lambda_n": "Pa",
    "lambda_t": "Pa",
    "jump_t": "m",
    "gap": "m",
    "state": "-",
}
MEANING = {
    "x": "node position",
    "normal_x": "outward unit normal n of the slave body",
    "lambda_n": "normal multiplier (contact traction on the slave is -lambda; "
    "lambda_n > 0: compression); empty where the node carries none",
    "lambda_t": "tangential multiplier along tau = (-n_y, n_x); |lambda_t| <= g",
    "jump_t": "tangential jump [u].tau (slave minus master; slave displacement for a rigid "
    "foundation)",
    "gap": "remaining normal gap to the obstacle, gap0 - u.n (0 in contact)",
    "state": "stick (|lambda_t| < g), slip (|lambda_t| = g), open (not touching; unilateral "
    "only), no_multiplier (crosspoint or uncovered node)",
}


@dataclass(frozen=True)
class ContactTable:
    """One row per node of the slave contact boundary, in order along it.

    points, normals : (k, 2).  weights : (k,) ∫φ_k ds (the node's share of the length).
    segments : (n_seg, 2) row indices of the boundary's segments (for the polyline VTU).
    lambda_n, lambda_t, jump_t : (k,), NaN where the node carries no such multiplier.
    state : (k,) one of STATES.  gap : (k,) or None (bilateral contact has none).
    """

    points: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    segments: np.ndarray
    lambda_n: np.ndarray
    lambda_t: np.ndarray
    jump_t: np.ndarray
    state: np.ndarray
    gap: np.ndarray | None = None

    @property
    def columns(self) -> dict[str, np.ndarray]:
        """The CSV columns, in order."""
        cols = {
            "x": self.points[:, 0],
            "y": self.points[:, 1],
            "normal_x": self.normals[:, 0],
            "normal_y": self.normals[:, 1],
            "lambda_n": self.lambda_n,
            "lambda_t": self.lambda_t,
            "jump_t": self.jump_t,
        }
        if self.gap is not None:
            cols["gap"] = self.gap
        cols["state"] = self.state
        return cols

    def totals(self) -> dict:
        """Contact force on the slave body −∫λ ds (N/m) and the lengths per state (m)."""
        n = self.normals
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)  # (k, 2) tangents
        lam = np.nan_to_num(self.lambda_n)[:, None] * n + np.nan_to_num(self.lambda_t)[:, None] * t
        force = -(self.weights[:, None] * lam).sum(axis=0)  # (2,)
        lengths = {f"{s}_length": float(self.weights[self.state == s].sum()) for s in STATES}
        counts = {s: int((self.state == s).sum()) for s in STATES}
        return {
            "force_on_slave": force.tolist(),
            "force_units": "N/m (per unit thickness)",
            **lengths,
            "counts": counts,
        }

    def records(self) -> list[dict]:
        """The rows as dicts (summary.json), NaN as None."""
        cols = self.columns
        out = []
        for i in range(self.points.shape[0]):
            row = {}
            for k, v in cols.items():
                x = v[i]
                row[k] = str(x) if k == "state" else (None if np.isnan(x) else float(x))
            out.append(row)
        return out


def write_contact_csv(path: Path, table: ContactTable) -> None:
    """contact.csv: '#' comment lines with units and meanings, a header row, one row a node."""
    cols = table.columns
    lines = ["# mixvi contact results, one row per node of the slave contact boundary"]
    for k in cols:
        meaning = MEANING.get(k) or MEANING.get(k.replace("y", "x"), "")
        lines.append(f"# {k} [{UNITS[k]}]: {meaning}")
    lines.append(",".join(cols))
    for i in range(table.points.shape[0]):
        cells = []
        for k, v in cols.items():
            x = v[i]
            cells.append(str(x) if k == "state" else ("" if np.isnan(x) else repr(float(x))))
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def write_contact_vtu(path: Path, table: ContactTable) -> None:
    """The contact boundary as a polyline VTU with λ, the jump, the state (code: index in
    STATES, and per state a 0/1 field) and the normal as point data."""
    import meshio

    k = table.points.shape[0]
    pts = np.concatenate([table.points, np.zeros((k, 1))], axis=1)  # (k, 3)
    code = np.array([STATES.index(s) for s in table.state], dtype=np.int32)
    point_data = {
        "normal": np.concatenate([table.normals, np.zeros((k, 1))], axis=1),
        "lambda_n": table.lambda_n,
        "lambda_t": table.lambda_t,
        "jump_t": table.jump_t,
        "state": code,
        **{f"is_{s}": (code == i).astype(np.int32) for i, s in enumerate(STATES)},
    }
    if table.gap is not None:
        point_data["gap"] = table.gap
    meshio.Mesh(pts, [("line", table.segments)], point_data=point_data).write(
        str(path), file_format="vtu"
    )


def symmetric_tensor(sxx, syy, szz, sxy) -> np.ndarray:
    """(n, 6) in VTK's symmetric tensor order XX, YY, ZZ, XY, YZ, XZ (ParaView shows it as a
    tensor with named components); YZ = XZ = 0 in plane strain."""
    z = np.zeros_like(sxx)
    return np.stack([sxx, syy, szz, sxy, z, z], axis=1)


def von_mises(sxx, syy, szz, sxy) -> np.ndarray:
    """√(½[(σxx−σyy)² + (σyy−σzz)² + (σzz−σxx)²] + 3σxy²)."""
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3.0 * sxy**2)


def write_pvd(path: Path, entries: list[tuple[float, int, str]]) -> None:
    """A ParaView collection: (timestep, part, file name relative to the .pvd) per dataset."""
    rows = "\n".join(
        f"    <DataSet timestep={quoteattr(repr(float(t)))} part={quoteattr(str(p))} "
        f"file={quoteattr(f)}/>"
        for t, p, f in entries
    )
    path.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
        f"{rows}\n  </Collection>\n</VTKFile>\n"
    )
