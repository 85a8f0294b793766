"""Every command × every plug-in (the shipped ones and a third-party one installed through its
`mixvi.plugins` entry point) at level 0, checking what each command writes: summary keys and
values finite and sensible, files present and non-empty, the rows of study/extremes/bench JSON.

The third-party plug-in (tests/thirdparty: a membrane on a sticky floor, contract v2) is
installed with pip into a throwaway folder put on sys.path (the venv is never modified); mixvi
finds it only through the entry point and knows nothing else of it."""

from __future__ import annotations

import importlib
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from problems.commands import main as cli
from problems.plugins import registry

THIRDPARTY = Path(__file__).resolve().parents[2] / "thirdparty"
SHIPPED = {  # plug-in → its cheapest shipped scene
    "contact": "rigid_foundation",
    "obstacle": "obstacle",
    "antiplane": "antiplane",
    "signorini": "signorini",
}
PLUGINS = [*SHIPPED, "sticky_floor"]
# sweep also runs the contact plug-in's 3D front and Coulomb scenes (their F, not g, is swept;
# slow tier: ~10 s each under load)
SWEPT = [
    *PLUGINS,
    pytest.param("coulomb_strip3d", marks=pytest.mark.slow),
    pytest.param("coulomb_strip", marks=pytest.mark.slow),
]
ONLY = {"contact": "gap = 0"}  # extremes: one level-0 row (time)
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The third-party package pip-installed into a fresh --target folder on sys.path."""
    site = tmp_path_factory.mktemp("site")
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation"]
        + ["--no-index", "--target", str(site), str(THIRDPARTY)],
        check=True,
        capture_output=True,
    )
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()
    try:
        yield site
    finally:
        sys.path.remove(str(site))
        sys.modules.pop("sticky_floor", None)
        importlib.invalidate_caches()


@pytest.fixture
def scene(request, installed) -> str:
    """The scene of the plug-in `request.param` (a path for the third-party one)."""
    name = request.param
    if name == "sticky_floor":
        return registry.get("sticky_floor").SCENE
    return SHIPPED.get(name, name)


def _finite(x, where: str = "") -> None:
    """Every number inside `x` (nested dicts/lists) is finite."""
    if isinstance(x, dict):
        for k, v in x.items():
            _finite(v, f"{where}.{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            _finite(v, f"{where}[{i}]")
    elif isinstance(x, float):
        assert math.isfinite(x), where


def _png(path: Path) -> None:
    assert path.is_file() and path.stat().st_size > 1000, path
    assert path.read_bytes()[:8] == PNG, path


def test_the_third_party_plugin_is_found_only_by_its_entry_point(installed):
    assert "sticky_floor" in registry.names() and "sticky_floor" not in registry.BUILTIN
    assert registry.get("sticky_floor").CONTRACT == 2


def test_scenes_lists_every_plugin(installed, capsys):
    assert cli.main(["scenes"]) == 0
    out = capsys.readouterr().out
    listed = out.split("plug-ins:")[1]
    for name in PLUGINS:
        assert f"\n  {name} " in listed, name
    assert "BROKEN" not in out
    for scene in SHIPPED.values():
        assert f"\n  {scene} " in out.split("plug-ins:")[0]


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_solve(scene, tmp_path, capsys):
    out = tmp_path / "solve"
    assert cli.main(["solve", scene, "--level", "0", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    plugin = registry.for_scene(_load(scene))
    assert s["plugin"] == plugin.NAME and s["level"] == 0 and s["converged"] is True
    assert 0 <= s["residual"] <= 1e-10 and s["iterations"] >= 1
    # a purely elastic scene has no potential unknowns; every count is an int, the rest positive
    assert all(isinstance(v, int) and v >= 0 for v in s["dofs"].values()), s["dofs"]
    assert all(v > 0 for k, v in s["dofs"].items() if k != "potential"), s["dofs"]
    _finite(s)
    assert s["files"], s
    for f in s["files"]:
        assert (out / f).stat().st_size > 0, f
    assert "  converged in " in capsys.readouterr().out


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_check(scene, tmp_path, capsys):
    path = tmp_path / "check.json"
    assert cli.main(["check", scene, "--level", "0", "--json", str(path)]) == 0
    recs = json.loads(path.read_text())["records"]
    assert [r["level"] for r in recs] == [0]
    r = recs[0]
    assert r["ok"] and not r["failures"] and r["unknowns"] > 0
    assert "ssn" in r["methods"] and len(r["methods"]) >= 2  # a second method to compare
    for m in r["methods"].values():
        assert m["converged"] and math.isfinite(m["residual"]) and m["residual"] <= 1e-6
    assert r["pairs"] and all(p["diff_u"] <= p["allowed"] for p in r["pairs"])


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_figures(scene, tmp_path, capsys):
    out = tmp_path / "fig"
    assert cli.main(["figures", scene, "--level", "0", "--out", str(out)]) == 0
    sweep = registry.for_scene(_load(scene)).SWEEP
    _png(out / sweep.file)
    lines = capsys.readouterr().out.splitlines()
    head = sweep.label.split(" [")[0]
    assert sum(ln.startswith(f"{head} = ") for ln in lines) == len(sweep.values or sweep.factors)


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_study(scene, tmp_path, capsys):
    from problems.commands.study import study_main

    out = tmp_path / "study"
    argv = [scene, "--levels", "0..1", "--solvers", "ssn", "--tols", "1e-8", "--no-progress"]
    assert study_main([*argv, "--out", str(out)]) == 0
    res = json.loads((out / "study.json").read_text())
    plugin = registry.for_scene(_load(scene))
    assert res["plugin"] == plugin.NAME and res["norms"] == list(plugin.NORMS)
    assert [r["level"] for r in res["records"]] == [0, 1]
    for r in res["records"]:
        assert set(r["err"]) == set(plugin.NORMS) and r["converged"] and r["h"] > 0
        _finite(r)
        assert all(v >= 0 for v in r["err"].values())
    h0, h1 = (r["h"] for r in res["records"])
    assert h1 < h0
    coarse = res["records"][0]["err"][plugin.NORMS[0]]
    assert coarse > 0  # level 0 differs from the exact solution or from level 1
    if res["reference"] == "level 1":  # the reference against itself: rounding, flagged
        assert res["records"][1]["err"][plugin.NORMS[0]] <= 1e-12 * coarse
        assert [r.get("reference", False) for r in res["records"]] == [False, True]
    for f in ("errors_vs_h.png", "errors_vs_time.png"):
        _png(out / f)


TIMES = ("time_s.build", "time_s.solve", "time_s.total")


@pytest.mark.parametrize("scene", SWEPT, indirect=True)
def test_sweep(scene, tmp_path, capsys):
    """Two values of the plug-in's own SWEEP parameter (`mixvi figures`'): a case folder with
    summary.json and the files of `mixvi solve` each, sweep.json, sweep.csv and a plot; the
    two cases differ in some output (the swept value reached the solve)."""
    from problems.commands.figures import sweep_values
    from problems.commands.sweep import sweep_main

    loaded = _load(scene)
    plugin = registry.for_scene(loaded)
    sweep, values = sweep_values(plugin.SWEEP, loaded)
    out = tmp_path / "sweep"
    argv = [scene, "--level", "0", "--set-list", f"{sweep.path}={values[0]!r},{values[-1]!r}"]
    assert sweep_main([*argv, "--plot", "iterations", "--no-progress", "--out", str(out)]) == 0
    res = json.loads((out / "sweep.json").read_text())
    assert res["plugin"] == plugin.NAME and res["parameters"] == {
        sweep.path: [values[0], values[-1]]
    }
    assert [c["set"][sweep.path] for c in res["cases"]] == [values[0], values[-1]]
    for c in res["cases"]:
        s = json.loads((out / c["case"] / "summary.json").read_text())
        assert s["plugin"] == plugin.NAME and s["converged"] is True and c["converged"]
        assert s["sweep"]["set"] == c["set"] and s["level"] == 0
        for f in s["files"]:
            assert (out / c["case"] / f).stat().st_size > 0, f
        if any(f.endswith(".vtu") for f in s["files"]):  # as mixvi solve: the collection
            assert "results.pvd" in s["files"], s["files"]
        _finite(s)
    if scene.startswith("coulomb_strip"):
        assert sweep.path == "contact.F"
    a, b = (c["outputs"] for c in res["cases"])
    assert any(a[k] != b.get(k) for k in a if k not in TIMES and isinstance(a[k], float)), a
    rows = (out / "sweep.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith(f"case,{sweep.path},error,")
    _png(out / "iterations.png")


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_extremes(scene, tmp_path, capsys):
    from problems.commands.extremes import extremes_main

    plugin = registry.for_scene(_load(scene))
    only = ["--only", ONLY[plugin.NAME]] if plugin.NAME in ONLY else []
    argv = ["--plugins", plugin.NAME, *only, "--out", str(tmp_path / "x")]
    assert extremes_main(argv) == 0
    recs = json.loads((tmp_path / "x" / "extremes.json").read_text())
    rows = registry.plugins()[plugin.NAME].extremes()  # the registered plug-in, both fronts
    want = [r.name for r in rows if not only or only[1] in r.name]
    assert [r["row"] for r in recs] == want and want
    for r in recs:
        assert r["plugin"] == plugin.NAME and r["ok"] and r["converged"], r
        assert r["residual"] <= 1e-8 and r["admissibility"] <= 1e-9 and r["agreement"], r
        assert not any(n.startswith("FAIL") for n in r["notes"]), r
        _finite(r)


@pytest.mark.parametrize("scene", PLUGINS, indirect=True)
def test_bench(scene, tmp_path, capsys):
    from problems.commands.bench import bench_main

    out = tmp_path / "bench.json"
    assert bench_main(["--scenes", scene, "--levels", "0..0", "--out", str(out)]) == 0
    recs = json.loads(out.read_text())["records"]
    assert [(r["scene"], r["level"], r["solver"]) for r in recs] == [(scene, 0, "ssn")]
    r = recs[0]
    assert not r.get("error") and r["converged"] and r["unknowns"] > 0, r
    assert r["time_nonlinear_s"] > 0 and r["time_linear_s"] > 0 and r["peak_mem_mb"] > 0
    _finite(r)


def _load(scene: str):
    from problems.scene import load_scene

    return load_scene(scene)


def test_the_output_checks_can_fail(tmp_path, monkeypatch, installed):
    """A NaN deep in a summary, a file that is not a PNG, and a plug-in whose postprocess
    returns a non-finite entry are each caught by the checks above."""
    with pytest.raises(AssertionError, match=r"\.a\[1\]\.b"):
        _finite({"a": [1.0, {"b": float("nan")}]})
    (tmp_path / "x.png").write_bytes(b"not a png" * 200)
    with pytest.raises(AssertionError):
        _png(tmp_path / "x.png")
    plugin = registry.get("sticky_floor")
    real = plugin.postprocess
    monkeypatch.setattr(plugin, "postprocess", lambda *a: {**real(*a), "bad": float("inf")})
    with pytest.raises(AssertionError, match=r"\.bad"):
        test_solve(plugin.SCENE, tmp_path, _NoCapture())


class _NoCapture:
    def readouterr(self):
        return type("R", (), {"out": "  converged in 1 Newton steps"})()
