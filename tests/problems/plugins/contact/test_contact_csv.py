"""One contact.csv writer for 2D and 3D (`results.ContactTable`): the same column names where
the quantities are the same. The 2D columns users read stay, in their order; 3D adds z, the
frame (tangent1_*, tangent2_*) and the second tangent's λ and jump; both write the friction
radius g and, for unilateral contact, the remaining gap. The g column is the contact state's
friction radius at the nodes with a tangential multiplier. Mutation: a front that writes no g
(or 3D without its gap) fails."""

from __future__ import annotations

import numpy as np
import pytest

import problems
from problems.output import results
from problems.output.results import write_contact_csv
from problems.plugins import registry
from problems.plugins.contact import output

OLD_2D = ["x", "y", "normal_x", "normal_y", "lambda_n", "lambda_t", "jump_t", "state"]
OLD_3D = ["x", "y", "z", *(f"{v}_{a}" for v in ("normal", "tangent1", "tangent2") for a in "xyz")]
OLD_3D += ["lambda_n", "lambda_t", "lambda_t2", "jump_t", "jump_t2", "g", "state"]


def _csv(name: str, tmp_path) -> tuple[dict[str, np.ndarray], dict, object]:
    """contact.csv's columns as arrays (state as text), the contact state and the model."""
    res = problems.solve_scene(name, level=0)
    front = registry.for_scene(res.model.scene)
    st = front.contact_state(res.model, res.solution)
    table = output.contact_table(res.model, res.solution)  # the table postprocess writes
    write_contact_csv(tmp_path / "contact.csv", table)
    lines = [x for x in (tmp_path / "contact.csv").read_text().splitlines() if x[:1] != "#"]
    head, rows = lines[0].split(","), [x.split(",") for x in lines[1:]]
    cols = {}
    for j, k in enumerate(head):
        v = [r[j] for r in rows]
        cols[k] = np.array(v) if k == "state" else np.array([float(x or "nan") for x in v])
    return cols, st, res.model


@pytest.mark.parametrize(
    "name,old,unilateral",
    [
        ("rigid_foundation", OLD_2D, False),
        ("piezo_liftoff", OLD_2D[:-1] + ["gap", "state"], True),
        ("block3d", OLD_3D, False),
        ("block3d_liftoff", OLD_3D, True),
    ],
)
def test_2d_and_3d_write_the_same_columns(name, old, unilateral, tmp_path):
    cols, st, model = _csv(name, tmp_path)
    head = list(cols)
    assert [k for k in head if k in old] == old  # every former column, in its order
    added = [k for k in head if k not in old]
    new = {(False, 2): ["g"], (True, 2): ["g"], (False, 3): [], (True, 3): ["gap"]}
    assert added == new[(unilateral, model.dimension)]
    c = model.contact
    if model.dimension == 2:  # g at the nodes carrying a tangential multiplier, else empty
        np.testing.assert_array_equal(cols["g"][c.rows_t], st["g"])
        assert np.isnan(np.delete(cols["g"], c.rows_t)).all()
    else:
        np.testing.assert_array_equal(cols["g"], st["g"])
    if unilateral:
        assert np.nanmin(cols["gap"]) >= 0.0 and np.isfinite(cols["gap"]).any()


@pytest.fixture(scope="module")
def paper_tables():
    """The contact tables the writer gives paper_two_body (2D) and its extrusion (3D), the
    3D node → 2D node map and the extrusion depth."""
    r2 = problems.solve_scene(problems.load_scene("paper_two_body"), level=0, tol=1e-12)
    r3 = problems.solve_scene(problems.load_scene("paper_two_body_extruded"), level=0, tol=1e-12)
    slave2 = r2.model.contact.tr.nodes  # 2D trace nodes (the slave's node ids)
    n2d = r2.model.contact.slave.mesh.n_nodes
    k = np.searchsorted(np.sort(slave2), r3.model.contact.tr.nodes % n2d)  # node i + l·N ↔ i
    where = np.argsort(slave2)[k]  # (k3,) 3D trace node → 2D trace index
    z = r3.model.contact.slave.mesh.points[:, 2]
    return (
        output.contact_table(r2.model, r2.solution),
        output.contact_table(r3.model, r3.solution),
        where,
        float(z.max() - z.min()),
    )


def _extruded_table_differences(t2, t3, where, depth) -> dict[str, float]:
    """Largest relative differences of the 3D table from the 2D one, node by node: position,
    normal, λ_n, λ_t and [u]_t as vectors (the frames differ: 2D τ, 3D t1, t2), g, state; the
    force (3D N = 2D N/m × depth) and the length/area per state."""
    lam_scale = np.nanmax(np.abs(t2.lambda_n))
    jump_scale = np.abs(t2.vectors("jump_t")).max()
    out = {
        "points": np.abs(t3.points[:, :2] - t2.points[where]).max(),
        "normals": np.abs(t3.normals - np.pad(t2.normals, ((0, 0), (0, 1)))[where]).max(),
        "lambda_n": np.abs(t3.lambda_n - t2.lambda_n[where]).max() / lam_scale,
        "g": np.abs(t3.bound - t2.bound[where]).max() / lam_scale,
        "state": float((t3.state != t2.state[where]).sum()),
    }
    for name, scale in (("lambda_t", lam_scale), ("jump_t", jump_scale)):
        v2 = np.pad(t2.vectors(name), ((0, 0), (0, 1)))[where]  # (k3, 3), z = 0
        out[name] = np.abs(t3.vectors(name) - v2).max() / scale
    tot2, tot3 = t2.totals(), t3.totals()
    f2 = np.array(tot2["force_on_slave"])
    out["force"] = np.abs(np.array(tot3["force_on_slave"]) - depth * np.append(f2, 0.0)).max()
    out["force"] /= np.abs(f2).max() * depth
    out["measures"] = max(
        abs(tot3[f"{s}_area"] - depth * tot2[f"{s}_length"]) for s in results.STATES
    )
    out["counts"] = float(
        sum(abs(tot3["counts"][s] - 2 * tot2["counts"][s]) for s in results.STATES)
    )  # one layer: every 2D node twice
    return {k: float(v) for k, v in out.items()}


def test_extruded_and_2d_writers_give_the_same_per_node_table(paper_tables):
    """The one writer on paper_two_body and its one-layer extrusion: the same row per node
    (measured ≤ 1e-13 relative), the same states, force × depth and lengths × depth."""
    d = _extruded_table_differences(*paper_tables)
    assert d["state"] == 0 and d["counts"] == 0, d
    for key, v in d.items():
        assert v <= 1e-10, (key, d)
    t2 = paper_tables[0]
    assert (t2.state == "stick").any() and (t2.state == "slip").any()  # both states compared


@pytest.mark.parametrize("dim", [2, 3])
def test_mutation_a_flipped_tangent_breaks_the_extruded_table(paper_tables, dim, monkeypatch):
    """A writer that reads λ_t along the negated tangents in one dimension (2D: −τ; 3D: −t1,
    −t2) leaves the other's table: λ_t and [u]_t differ."""
    frame = results.ContactTable.tangent_frame.fget
    flip = (lambda t: t.tangents is None) if dim == 2 else (lambda t: t.tangents is not None)
    monkeypatch.setattr(
        results.ContactTable,
        "tangent_frame",
        property(lambda t: -frame(t) if flip(t) else frame(t)),
    )
    d = _extruded_table_differences(*paper_tables)
    assert d["lambda_t"] > 1e-3 and d["jump_t"] > 1e-3, d


def test_the_manual_names_every_state_contact_csv_writes():
    """docs/design.md's contact.csv entry lists every `state` the writer can write
    (results.STATES: normal_only came with the one writer, and was missing there)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[4] / "docs" / "design.md").read_text()
    start = text.index("`state` is `stick`")
    entry = text[start : text.index("`jump_t` is", start)]
    assert [s for s in results.STATES if f"`{s}`" not in entry] == []
