"""`paths.probe` and `paths.write_file` remove only the temporary files they created: a file
that already has the name they would use (a leftover of another process with the same pid, or
anything else) is left as it was when they fail on it."""

from __future__ import annotations

import os

import pytest

from problems.errors import SceneError
from problems.output import paths


def test_probe_leaves_a_file_of_its_name_that_it_did_not_create(tmp_path):
    taken = tmp_path / f"{paths.STAGING}probe-{os.getpid()}"
    taken.write_text("not the probe's")
    with pytest.raises(SceneError, match="mixvi can write"):
        paths.probe(tmp_path, "--out", tmp_path / "o")
    assert taken.read_text() == "not the probe's"


def test_probe_leaves_nothing_when_it_succeeds(tmp_path):
    paths.probe(tmp_path, "--out", tmp_path / "o")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("replace", [True, False])
def test_write_file_leaves_a_file_of_its_temporary_name(tmp_path, monkeypatch, replace):
    monkeypatch.setattr(paths.os, "urandom", lambda n: b"\x01" * n)
    target = tmp_path / "marker.json"
    taken = tmp_path / f"{paths.STAGING}{os.getpid()}-{'01' * 4}-{target.name}"
    taken.write_text("not write_file's")
    with pytest.raises(FileExistsError):
        paths.write_file(target, "{}", replace=replace)
    assert taken.read_text() == "not write_file's" and not target.exists()
