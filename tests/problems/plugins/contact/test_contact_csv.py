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
