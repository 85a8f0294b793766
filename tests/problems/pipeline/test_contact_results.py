"""The API's contact results speak the words of contact.csv and contact.vtu (lambda_n,
lambda_t, lambda_t2, jump_t, jump_t2, state); the old keys still read, with a
DeprecationWarning, for one release."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import problems
from problems.pipeline.contact_results import RENAMED, RETIRED, ContactResults

# the per-node quantities that both the API and the written files name
VOCABULARY = {"lambda_n", "lambda_t", "lambda_t2", "jump_t", "jump_t2", "state"}


def _written_names(res, tmp_path) -> tuple[set[str], set[str]]:
    """(CSV header names, VTU point data names) of the run's contact.csv and contact.vtu."""
    from problems.plugins import registry

    plugin = registry.for_scene(res.model.scene)
    plugin.postprocess(res.model, res.solution, tmp_path)
    header = next(
        line for line in (tmp_path / "contact.csv").read_text().splitlines() if line[:1] != "#"
    )
    vtu = set(re.findall(r'Name="([^"]+)"', (tmp_path / "contact.vtu").read_text()))
    return set(header.split(",")), vtu


@pytest.mark.parametrize("name", ["rigid_foundation", "block3d"])
def test_api_names_are_the_csv_and_vtu_column_names(name, tmp_path):
    res = problems.solve_scene(name, level=0)
    csv, vtu = _written_names(res, tmp_path)
    api = set(res.contact) & VOCABULARY
    assert api == csv & VOCABULARY, (sorted(api), sorted(csv))
    assert api == vtu & VOCABULARY, (sorted(api), sorted(vtu))
    assert not set(res.contact) & (set(RENAMED) | set(RETIRED))  # no old name is listed


def test_old_keys_read_with_a_deprecation_warning():
    raw = {
        "lam_n": np.array([1.0, 2.0]),
        "lam_t": np.array([0.5, -0.5]),
        "slip": np.array([True, False]),
        "state": np.array(["slip", "stick"]),
        "lemma_4_2": 0.0,
    }
    c = ContactResults(raw)
    assert sorted(c) == ["lambda_n", "lambda_t", "lemma_4_2", "state"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert c["lambda_t"] is raw["lam_t"]  # the new names read silently
    for old, new in (("lam_n", "lambda_n"), ("lam_t", "lambda_t")):
        with pytest.warns(DeprecationWarning, match=rf"contact\['{old}'\].*contact\['{new}'\]"):
            assert c[old] is c[new]
    with pytest.warns(DeprecationWarning, match="state == 'slip'"):
        assert c["slip"] is raw["slip"]
    with pytest.raises(KeyError):
        c["lam_t1"]  # a 3D name this (2D) state never had
