"""docs/plugins.md cannot rot: its module and scene are extracted and run, and packaged as a
third-party plug-in found through the `mixvi.plugins` entry point group."""

from __future__ import annotations

import importlib
import importlib.util
import json
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest

import vi_core
from problems.commands import main as cli
from problems.plugins import registry
from problems.plugins.contract import conforms
from problems.scene import load_scene

GUIDE = Path(__file__).resolve().parents[3] / "docs" / "plugins.md"


def _block(first_line: str) -> str:
    """The fenced code block of the guide whose first line is `first_line`."""
    for body in re.findall(r"```[a-z]*\n(.*?)```", GUIDE.read_text(), flags=re.S):
        if body.startswith(first_line + "\n"):
            return body
    raise AssertionError(f"no code block starting with {first_line!r} in {GUIDE}")


def _write_plugin(d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "sticky.py").write_text(_block("# sticky.py"))
    (d / "sticky.toml").write_text(_block("# sticky.toml"))
    return d / "sticky.toml"


@pytest.fixture
def sticky_module(tmp_path):
    scene = _write_plugin(tmp_path / "src")
    sys.path.insert(0, str(tmp_path / "src"))
    try:
        yield importlib.import_module("sticky"), scene
    finally:
        sys.path.remove(str(tmp_path / "src"))
        sys.modules.pop("sticky", None)


def test_guide_module_is_50_lines():
    lines = [ln for ln in _block("# sticky.py").splitlines() if ln.strip()]
    assert len(lines) <= 50


def test_guide_example_solves_with_every_solver(sticky_module, tmp_path):
    mod, scene_path = sticky_module
    assert conforms(mod) == []
    model = mod.build(load_scene(str(scene_path)), None)
    sols = {
        m: vi_core.solve(model.vi, method=m, tol=1e-10, **opts)
        for m, opts in (("ssn", {}), ("conic", {}), ("homotopy", {"report_constants": False}))
    }
    for s in sols.values():
        assert s.converged and s.residual <= 1e-10
    ref = sols["ssn"]
    for s in sols.values():
        assert np.linalg.norm(s.u - ref.u) <= 1e-6 * np.linalg.norm(ref.u)
    out = mod.postprocess(model, ref, tmp_path)
    # the floor holds somewhere (near the boundary) and lets go in the middle
    assert 0 < out["stuck_nodes"] < model.vi.n
    assert (tmp_path / "sticky.vtu").is_file()


def _hand_wheel(pkg: Path, dest: Path) -> Path:
    """A wheel of the guide's package written directly (the venv has no `wheel` package, so
    setuptools cannot build one offline); name, version and entry points come from the
    guide's pyproject.toml, so that file is still what is tested."""
    meta = tomllib.loads((pkg / "pyproject.toml").read_text())["project"]
    name, version = meta["name"].replace("-", "_"), meta["version"]
    info = f"{name}-{version}.dist-info"
    eps = "".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in table.items())
        for group, table in meta["entry-points"].items()
    )
    files = {
        "sticky.py": (pkg / "sticky.py").read_text(),
        f"{info}/METADATA": f"Metadata-Version: 2.1\nName: {meta['name']}\nVersion: {version}\n",
        f"{info}/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\n"
        "Tag: py3-none-any\n",
        f"{info}/entry_points.txt": eps,
    }
    whl = dest / f"{name}-{version}-py3-none-any.whl"
    with zipfile.ZipFile(whl, "w") as z:
        for arc, text in files.items():
            z.writestr(arc, text)
        z.writestr(f"{info}/RECORD", "".join(f"{a},,\n" for a in files) + f"{info}/RECORD,,\n")
    return whl


def test_guide_example_as_installed_entry_point(tmp_path, capsys):
    pkg = tmp_path / "pkg"
    scene = _write_plugin(pkg)
    (pkg / "pyproject.toml").write_text(_block("[build-system]"))
    site = tmp_path / "site"
    source = str(pkg) if importlib.util.find_spec("wheel") else str(_hand_wheel(pkg, tmp_path))
    # --target: the throwaway install lives in tmp_path, the shared venv is never modified
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--target",
            str(site),
            source,
        ],
        check=True,
        capture_output=True,
    )
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()
    try:
        assert "sticky" in registry.names()
        assert registry.get("sticky").NAME == "sticky"
        assert cli.main(["scenes"]) == 0
        listed = capsys.readouterr().out
        assert "plug-ins:" in listed and "\n  sticky" in listed
        out = tmp_path / "out"
        assert cli.main(["solve", str(scene), "--out", str(out)]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["plugin"] == "sticky" and summary["converged"]
        assert (out / "sticky.vtu").is_file()
    finally:
        sys.path.remove(str(site))
        sys.modules.pop("sticky", None)
        importlib.invalidate_caches()
    assert "sticky" not in registry.names()
