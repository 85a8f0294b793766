"""Results as data: the contact table (contact.csv, contact.vtu, summary entries), named VTU
tensors, von Mises — the files a ParaView or pandas user reads (the .pvd collection:
`problems.output.collection`).

Conventions (docs/design.md, "Results"): lengths in m, multipliers (contact tractions) in Pa,
forces per unit thickness in N/m. The multiplier λ = λ_n n + λ_t τ enters the equations as
A u + Bᵀλ = f, so the traction the other side exerts on the slave body is −λ; for the
bilateral contact of the contact plug-in λ_n > 0 is compression, and for unilateral contact
(signorini) the pressure is λ_n ≥ 0 as well. τ = (−n_y, n_x): n turned counterclockwise by 90°.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# the node states (vi_core.states); contact.vtu's `state` is the index here (normal_only last,
# so the others keep their codes)
STATES = ("stick", "slip", "open", "no_multiplier", "ambiguous", "normal_only")
CSV_TITLE = "mixvi contact results, one row per node of the slave contact boundary"
AXES = "xyz"
UNITS = {"lambda_n": "Pa", "lambda_t": "Pa", "jump_t": "m", "g": "Pa", "gap": "m", "state": "-"}
MEANING = {
    "x": "node position",
    "normal_x": "outward unit normal n of the slave body",
    "tangent_x": "unit tangent t of the multiplier lambda_t",
    "tangent1_x": "unit tangent t1 of the multiplier lambda_t (t1, t2, n right-handed)",
    "tangent2_x": "second unit tangent t2 of the multiplier lambda_t2 (t2 = n x t)",
    "lambda_n": "normal multiplier (contact traction on the slave is -lambda; "
    "lambda_n > 0: compression); empty where the node carries none",
    "lambda_t": "tangential multiplier along tau = (-n_y, n_x); |lambda_t| <= {bound}",
    "jump_t": "tangential jump [u].tau (slave minus master; slave displacement for a rigid "
    "foundation)",
    "g": "friction radius of the solution at the node ({bound}; 0 where open); empty where the "
    "node carries no tangential multiplier",
    "gap": "remaining normal gap to the obstacle, gap0 - u.n (0 in contact)",
    "state": "stick (|lambda_t| < {bound}), slip (|lambda_t| = {bound}), open (not touching; "
    "unilateral only), no_multiplier (crosspoint or uncovered node), ambiguous (not settled at the "
    "achieved residual: vi_core.states)",
}
# the friction bound of each friction law, as the meanings write it ({bound})
BOUNDS = {"tresca": "g", "coulomb": "F lambda_n"}
# with explicit tangent columns the tangential quantities are along them, not along τ
MEANING_WITH_TANGENTS = {
    "lambda_t": "tangential multiplier along the first tangent (tangent_* or tangent1_*); "
    "|lambda_t| <= {bound}",
    "lambda_t2": "tangential multiplier along t2 (the tangent2_* columns)",
    "jump_t": "tangential jump [u].t (slave minus master; slave displacement for a rigid "
    "foundation)",
    "jump_t2": "tangential jump [u].t2",
}


@dataclass(frozen=True)
class ContactTable:
    """One row per node of the slave contact boundary, in order along it; the columns are
    those that apply to the contact law (`columns`).

    points : (k, d) positions, d = 2 or 3.  normals : (k, d) outward unit normals of the slave.
    weights : (k,) ∫φ_k ds (the node's share of the boundary's length or area).
    weights_n, weights_t : (k,) or None (= weights): the class weights ∫ψ̃_k of the normal and
        the tangential multipliers (dual mortar: ∫φ_k plus what merged crosspoint nodes gave).
    segments : (n_f, v) row indices of the boundary's facets: segments (cell_type "line", a
        curve) or faces ("triangle", "quad": a surface), the cells of contact.vtu.
    lambda_n : (k,) or None (a law without a normal multiplier, e.g. antiplane friction).
    lambda_t, jump_t : (k,) or (k, d_t) per tangent; NaN where the node carries none.
    tangents : None (2D: τ = (−n_y, n_x), no columns) or (k, d_t, D) unit tangents, D ≥ d
        (D = 3 with d = 2: antiplane, whose tangent is e_z), written as tangent_* (one) or
        tangent1_*, tangent2_* (two: a 3D surface).
    state : (k,) one of STATES.  gap : (k,) or None (bilateral contact has none).
    bound : (k,) or None: the friction radius of the solution per node (column g, Pa; NaN
        where the node carries no tangential multiplier).
    meanings : column name → meaning, replacing MEANING's line for a plug-in's own law.
    friction : "tresca" (bound g) or "coulomb" (bound F λ_n): the bound the meanings name.
    """

    points: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    segments: np.ndarray
    lambda_n: np.ndarray | None
    lambda_t: np.ndarray
    jump_t: np.ndarray
    state: np.ndarray
    gap: np.ndarray | None = None
    tangents: np.ndarray | None = None
    meanings: dict[str, str] = field(default_factory=dict)
    friction: str = "tresca"
    bound: np.ndarray | None = None
    weights_n: np.ndarray | None = None
    weights_t: np.ndarray | None = None
    cell_type: str = "line"

    @property
    def tangent_frame(self) -> np.ndarray:
        """(k, d_t, D) the unit tangents (2D default: τ = (−n_y, n_x), d_t = 1, D = 2)."""
        if self.tangents is not None:
            return self.tangents
        n = self.normals
        return np.stack([-n[:, 1], n[:, 0]], axis=1)[:, None, :]

    def tangent_names(self) -> list[str]:
        """The names of the explicit tangents: tangent (one), tangent1, tangent2 (two)."""
        n = 0 if self.tangents is None else self.tangents.shape[1]
        return ["tangent"] if n == 1 else [f"tangent{j + 1}" for j in range(n)]

    @staticmethod
    def _split(name: str, v: np.ndarray) -> dict[str, np.ndarray]:
        """(k,) → {name}; (k, j) → {name, name2, …}."""
        if v.ndim == 1:
            return {name: v}
        return {name + ("" if j == 0 else str(j + 1)): v[:, j] for j in range(v.shape[1])}

    @property
    def columns(self) -> dict[str, np.ndarray]:
        """The CSV columns, in order: x, y[, z], normal_*, [tangent_* | tangent1_*, tangent2_*,]
        lambda_n, lambda_t[, lambda_t2], jump_t[, jump_t2][, g][, gap], state (those that
        apply)."""
        d = self.points.shape[1]
        cols = {AXES[i]: self.points[:, i] for i in range(d)}
        cols |= {f"normal_{AXES[i]}": self.normals[:, i] for i in range(d)}
        if self.tangents is not None:
            dim = self.tangents.shape[2]
            for j, name in enumerate(self.tangent_names()):
                cols |= {f"{name}_{AXES[i]}": self.tangents[:, j, i] for i in range(dim)}
        if self.lambda_n is not None:
            cols["lambda_n"] = self.lambda_n
        cols |= self._split("lambda_t", self.lambda_t)
        cols |= self._split("jump_t", self.jump_t)
        if self.bound is not None:
            cols["g"] = self.bound
        if self.gap is not None:
            cols["gap"] = self.gap
        cols["state"] = self.state
        return cols

    def unit(self, column: str) -> str:
        """The unit of a column."""
        if column in AXES:
            return "m"
        if column.startswith(("normal_", "tangent")):
            return "1"
        return UNITS[column.rstrip("0123456789")]

    def meaning(self, column: str) -> str:
        """The header comment's meaning of a column (one line for x, y, z and for the
        components of a vector: normal_y and normal_z read normal_x's)."""
        if column in AXES:
            column = "x"
        elif column.endswith(("_y", "_z")):
            column = column[:-1] + "x"
        if column in self.meanings:
            return self.meanings[column]
        if self.tangents is not None and column in MEANING_WITH_TANGENTS:
            text = MEANING_WITH_TANGENTS[column]
        else:
            text = MEANING.get(column, "")
        return text.replace("{bound}", BOUNDS[self.friction])

    def vectors(self, name: str) -> np.ndarray:
        """(k, D) lambda_t or jump_t as a vector Σ_j v_j t_j of the tangents' space (0 where
        the node carries none)."""
        t = self.tangent_frame  # (k, d_t, D)
        v = np.nan_to_num(getattr(self, name)).reshape(t.shape[0], -1)  # (k, d_t)
        return np.einsum("kj,kjd->kd", v, t)

    def totals(self) -> dict:
        """Contact force on the slave body −∫λ_h = −Σ_k (w_n,k λ_n,k n_k + w_t,k λ_t,k t_k)
        with the class weights (the resultant of its nodal contact forces −Bᵀλ; N/m in 2D, N
        in 3D), with the components of the tangents' space (x, y in plane; x, y, z for
        antiplane and 3D), the length (2D, m) or area (3D, m²) per state and the nodes per
        state. The measures sum the nodal weights ∫φ_k, a partition of the boundary (the class
        weights are not: where a node keeps one class's multiplier and gives the other's dual
        function to its neighbour, its share would count twice)."""
        W = self.weights
        w_n = W if self.weights_n is None else self.weights_n
        w_t = W if self.weights_t is None else self.weights_t
        lam = w_t[:, None] * self.vectors("lambda_t")  # (k, D)
        if self.lambda_n is not None:
            n = np.zeros_like(lam)  # (k, D) the normal, padded to D
            n[:, : self.normals.shape[1]] = self.normals
            lam = lam + (w_n * np.nan_to_num(self.lambda_n))[:, None] * n
        force = -lam.sum(axis=0)  # (D,)
        plane = self.points.shape[1] == 2
        measure = "length" if plane else "area"
        return {
            "force_on_slave": force.tolist(),
            "force_units": "N/m (per unit thickness)" if plane else "N",
            **{f"{s}_{measure}": float(W[self.state == s].sum()) for s in STATES},
            "counts": {s: int((self.state == s).sum()) for s in STATES},
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

    def summary(self) -> dict:
        """summary.json's `contact` entries of the table: `nodes` (those carrying a
        multiplier), the stick/slip/ambiguous (and, for unilateral contact, open) counts, the
        totals
        and the rows."""
        totals = self.totals()
        counts = {k: totals["counts"][k] for k in ("stick", "slip", "open", "ambiguous")}
        if self.gap is None:
            del counts["open"]
        nodes = int((self.state != "no_multiplier").sum())
        return {"nodes": nodes, **counts, **totals, "table": self.records()}


def write_contact_csv(path: Path, table: ContactTable) -> None:
    """contact.csv: '#' comment lines with units and meanings, a header row, one row a node."""
    cols = table.columns
    notes = [f"{k} [{table.unit(k)}]: {table.meaning(k)}".rstrip(": ") for k in cols]
    write_csv(path, [CSV_TITLE, *notes], cols)


def write_csv(path: Path, comments: list[str], cols: dict[str, np.ndarray]) -> None:
    """A results CSV: one '#' line per comment, a header row of the column names, one row per
    entry of the (k,) columns: numbers as repr(float), NaN as an empty cell, `state` as text."""
    lines = [f"# {c}" for c in comments]
    lines.append(",".join(cols))
    for i in range(len(next(iter(cols.values())))):
        cells = []
        for k, v in cols.items():
            x = v[i]
            cells.append(str(x) if k == "state" else ("" if np.isnan(x) else repr(float(x))))
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def _pad3(v: np.ndarray) -> np.ndarray:
    """(k, d) → (k, 3) with zeros (VTK vectors are 3D)."""
    return np.concatenate([v, np.zeros((v.shape[0], 3 - v.shape[1]))], axis=1)


def write_contact_vtu(path: Path, table: ContactTable) -> None:
    """The contact boundary (its segments or faces, `cell_type`) as a VTU with the table's
    λ, jump, g and gap columns, λ_t and [u]_t as vectors (lambda_t_vec, jump_t_vec), the
    state (code: index in STATES, and per state a 0/1 field), the normal and the explicit
    tangents as point data."""
    import meshio

    code = np.array([STATES.index(s) for s in table.state], dtype=np.int32)
    point_data = {"normal": _pad3(table.normals)}
    for j, name in enumerate(table.tangent_names()):
        point_data[name] = _pad3(table.tangents[:, j])
    cols = table.columns
    point_data |= {
        k: v for k, v in cols.items() if k.startswith(("lambda", "jump")) or k in ("g", "gap")
    }
    point_data |= {f"{k}_vec": _pad3(table.vectors(k)) for k in ("lambda_t", "jump_t")}
    point_data["state"] = code
    point_data |= {f"is_{s}": (code == i).astype(np.int32) for i, s in enumerate(STATES)}
    meshio.Mesh(
        _pad3(table.points), [(table.cell_type, table.segments)], point_data=point_data
    ).write(str(path), file_format="vtu")


def write_contact(outdir: Path, table: ContactTable) -> tuple[list[str], dict]:
    """contact.csv and contact.vtu in `outdir`; returns (the file names, table.summary())."""
    write_contact_csv(outdir / "contact.csv", table)
    write_contact_vtu(outdir / "contact.vtu", table)
    return ["contact.csv", "contact.vtu"], table.summary()


VTK_ORDER = [0, 1, 2, 5, 3, 4]  # Voigt (xx, yy, zz, yz, xz, xy) → VTK (XX, YY, ZZ, XY, YZ, XZ)


def von_mises(s: np.ndarray) -> np.ndarray:
    """(n,) von Mises stress √(½[(σxx−σyy)² + (σyy−σzz)² + (σzz−σxx)²] + 3(σxy² + σyz² + σxz²))
    of Voigt stresses s (n, 6) in the order xx, yy, zz, yz, xz, xy."""
    xx, yy, zz, yz, xz, xy = s.T
    return np.sqrt(
        0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3 * (xy**2 + yz**2 + xz**2)
    )
