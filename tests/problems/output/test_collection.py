"""The one .pvd writer (problems.output.collection): read back as XML, parts per time step,
refusals of what ParaView could not open."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from problems.output.collection import pvd_text, write_pvd


def _datasets(path):
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    return [
        (float(d.get("timestep")), int(d.get("part")), d.get("file")) for d in root.iter("DataSet")
    ]


def test_a_load_path_collection_reads_back(tmp_path):
    steps = [(0.0, "step_0/body.vtu"), (0.5, "step_1/body.vtu"), (1.0, "step_2/body.vtu")]
    write_pvd(tmp_path / "load_path.pvd", steps)
    assert _datasets(tmp_path / "load_path.pvd") == [(t, 0, f) for t, f in steps]


@given(
    st.lists(
        st.tuples(st.integers(0, 5), st.sampled_from(["a.vtu", "b.vtu", "levels/1/c.vtu"])),
        max_size=12,
    )
)
def test_datasets_of_one_time_are_its_parts_in_the_order_given(datasets):
    root = ET.fromstring(pvd_text(datasets))
    got = [
        (float(d.get("timestep")), int(d.get("part")), d.get("file")) for d in root.iter("DataSet")
    ]
    assert [(t, f) for t, _, f in got] == [(float(t), f) for t, f in datasets]
    for t in {t for t, _ in datasets}:  # parts 0, 1, 2, … within each time, in order
        assert [p for tt, p, _ in got if tt == t] == list(
            range(sum(1 for s, _ in datasets if s == t))
        )


def test_odd_file_names_are_escaped():
    root = ET.fromstring(pvd_text([(1, 'a "quoted" & <odd>.vtu')]))
    assert next(root.iter("DataSet")).get("file") == 'a "quoted" & <odd>.vtu'


@pytest.mark.parametrize(
    ("t", "f"),
    [
        (np.nan, "a.vtu"),
        (np.inf, "a.vtu"),
        ("1", "a.vtu"),
        (True, "a.vtu"),
        (0, "/abs.vtu"),
        (0, "../up.vtu"),
        (0, ""),
    ],
)
def test_refused_datasets(t, f):
    with pytest.raises(ValueError, match="pvd dataset"):
        pvd_text([(t, f)])
