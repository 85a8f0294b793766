"""`mixvi new` (a scene template, never overwriting) and scene names without `.toml`."""

from __future__ import annotations

from pathlib import Path

import pytest

from problems.commands.main import main
from problems.scene import SCENES_DIR, find_scene


def test_new_writes_a_template_that_validates_elsewhere(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["new", "plate_with_hole", "part.toml"]) == 0
    text = (tmp_path / "part.toml").read_text()
    assert text.startswith("# part.toml: a mixvi scene written by `mixvi new plate_with_hole")
    assert "mixvi validate part.toml" in text and "mixvi solve part.toml" in text
    mesh = (SCENES_DIR / "meshes" / "plate_with_hole.msh").resolve().as_posix()
    assert f'mesh = "{mesh}"' in text and Path(mesh).is_file()  # found from the new folder
    assert main(["new", "part", "copy.toml"]) == 0  # a local scene named without .toml
    assert (tmp_path / "copy.toml").read_text().endswith(text)
    assert main(["new", "obstacle", "ob.toml"]) == 0
    assert main(["validate", "ob"]) == 0  # a local name without .toml
    assert "valid" in capsys.readouterr().out


def test_new_never_overwrites(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.toml").write_text("# my own scene\n")
    assert main(["new", "obstacle", "mine.toml"]) == 2
    assert "never overwrites" in capsys.readouterr().err
    assert (tmp_path / "mine.toml").read_text() == "# my own scene\n"
    assert main(["new", "obstacle", "mine.txt"]) == 2
    assert main(["new", "nosuch", "x.toml"]) == 2
    assert main(["new", "obstacle", "no/such/folder/x.toml"]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.toml"]  # nothing else written


def test_a_name_both_local_and_shipped_is_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert find_scene("obstacle") == SCENES_DIR / "obstacle.toml"
    (tmp_path / "obstacle.toml").write_text("")
    from problems.errors import SceneError

    with pytest.raises(SceneError, match="both the file obstacle.toml and a shipped scene"):
        find_scene("obstacle")
    assert find_scene("obstacle.toml").resolve() == (tmp_path / "obstacle.toml").resolve()
    assert find_scene(str(SCENES_DIR / "obstacle.toml")) == SCENES_DIR / "obstacle.toml"
