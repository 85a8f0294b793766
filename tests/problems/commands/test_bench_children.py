"""`mixvi bench` with child processes that crash, raise, hang or run out of memory, and
`mixvi scenes` with broken third-party plug-ins and scenes.

A throwaway plug-in `wobbly` is installed the way a third-party package is found (a module and
a `*.dist-info/entry_points.txt` in the `mixvi.plugins` group, on PYTHONPATH). It builds the
obstacle scene, but inside a bench child (`multiprocessing.parent_process()` is set) it
misbehaves as its scene's `[wobble] mode` says. The installed `mixvi` runs as a subprocess.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from problems.scene import SCENES_DIR

MIXVI = str(Path(sys.executable).with_name("mixvi"))

WOBBLY = '''
"""A plug-in that misbehaves inside a bench child, as its scene's [wobble] mode says."""
import copy, multiprocessing, os, signal, time
import numpy as np
from problems.plugins import obstacle
from problems.scene import Scene, Section
from problems.scene.fields import Text
from problems.scene.model import head

CONTRACT = 2
NAME = "wobbly"
DESCRIPTION = "test plug-in: crashes, raises, hangs or runs out of memory in a child"


class Wobble(Section):
    mode: Text
    pidfile: Text | None = None


class SCENE_MODEL(obstacle.SCENE_MODEL):  # an obstacle scene with [wobble] (contract 2)
    scene: head(NAME, 2)
    wobble: Wobble


def build(scene, level=None):
    data = copy.deepcopy(scene.data)
    wobble = data.pop("wobble", {})
    data["scene"]["plugin"] = "obstacle"
    if wobble.get("mode") == "bug":  # a bug in the plug-in, in any process
        raise RuntimeError("wobbly: a bug, not bad input")
    if multiprocessing.parent_process() is not None:
        mode = wobble.get("mode")
        if "pidfile" in wobble:
            tmp = wobble["pidfile"] + ".part"  # written whole, then renamed: never read empty
            with open(tmp, "w") as fh:
                fh.write(str(os.getpid()))
            os.replace(tmp, wobble["pidfile"])
        if mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if mode == "segv":
            os.kill(os.getpid(), signal.SIGSEGV)
        if mode == "exit":
            os._exit(7)
        if mode == "raise":
            raise ValueError("wobbly: an internal error in the child")
        if mode == "memory":
            np.ones(10**15)
        if mode == "hang":
            while True:
                time.sleep(1)
    return obstacle.build(Scene(data, scene.path, scene.name), level)


postprocess = obstacle.postprocess
'''

BROKEN = 'raise ImportError("broken on purpose")\n'


def install(site: Path) -> None:
    """wobbly (working) and broken (import fails) as entry-point plug-ins in `site`; wobbly
    also ships a scene folder with one good and one unreadable scene."""
    site.mkdir(parents=True, exist_ok=True)
    (site / "wobbly.py").write_text(WOBBLY + "SCENES_DIR = __file__[:-3] + '_scenes'\n")
    scenes = site / "wobbly_scenes"
    scenes.mkdir()
    (scenes / "fine.toml").write_text(scene_text("none"))
    (scenes / "garbled.toml").write_text("[scene\nplugin = ")
    (site / "brokenplug.py").write_text(BROKEN)
    info = site / "wobbly_test-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: wobbly-test\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[mixvi.plugins]\nwobbly = wobbly\nbrokenplug = brokenplug\n"
    )


def scene_text(mode: str, pidfile: Path | None = None) -> str:
    text = (SCENES_DIR / "obstacle.toml").read_text()
    text = text.replace('plugin = "obstacle"', 'plugin = "wobbly"')
    extra = f"pidfile = {json.dumps(str(pidfile))}\n" if pidfile else ""
    return text + f'\n[wobble]\nmode = "{mode}"\n{extra}'


@pytest.fixture
def site(tmp_path):
    s = tmp_path / "site"
    install(s)
    env = {**os.environ, "PYTHONPATH": str(s), "MPLBACKEND": "Agg"}
    return s, env


def mixvi(args, env, cwd, timeout=300):
    return subprocess.run(
        [MIXVI, *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


def test_failed_children_become_rows_and_the_table_is_still_written(site, tmp_path):
    _, env = site
    modes = ["kill", "segv", "exit", "raise", "memory", "hang", "none"]
    for m in modes:
        (tmp_path / f"{m}.toml").write_text(scene_text(m))
    out = tmp_path / "bench.json"
    scenes = ",".join(str(tmp_path / f"{m}.toml") for m in modes)
    # --timeout counts from the child's start, imports included: 8 s timed out the crashing
    # children on a slow machine (one core shared with a busy process, niced) before they
    # crashed; the subprocess timeout is what catches a wait without a limit
    argv = ["bench", "--scenes", scenes, "--levels", "0", "--timeout", "20", "--out", str(out)]
    r = mixvi(argv, env, tmp_path, timeout=600)
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    rows = json.loads(out.read_text())["records"]
    cause = {Path(m).stem: None for m in modes}
    for m, row in zip(modes, rows, strict=True):
        cause[m] = row.get("error")
    assert "SIGKILL" in cause["kill"] and "out of memory" in cause["kill"]
    assert "SIGSEGV" in cause["segv"]
    assert "status 7" in cause["exit"]
    assert "ValueError" in cause["raise"] and "internal error in the child" in cause["raise"]
    assert "out of memory" in cause["memory"]
    assert "timed out after 20 s" in cause["hang"]
    assert cause["none"] is None and rows[-1]["converged"]
    assert "FAILED" in r.stdout and r.stdout.count("FAILED") == 6


def test_sigint_to_bench_ends_the_child_and_keeps_the_old_table(site, tmp_path):
    _, env = site
    pidfile = tmp_path / "child.pid"
    (tmp_path / "hang.toml").write_text(scene_text("hang", pidfile))
    out = tmp_path / "bench.json"
    out.write_text('{"old": true}')  # not mixvi's: replacing it needs --overwrite
    p = subprocess.Popen(
        [MIXVI, "bench", "--scenes", str(tmp_path / "hang.toml"), "--levels", "0",
         "--out", str(out), "--overwrite"],
        env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not pidfile.exists() and time.monotonic() < deadline:  # renamed into place whole
        time.sleep(0.05)
    assert pidfile.exists(), "the child never started"
    child = int(pidfile.read_text())
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err
    assert err.strip().splitlines() == ["mixvi: interrupted by SIGINT"]
    assert out.read_text() == '{"old": true}'
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".mixvi-tmp")]
    deadline = time.monotonic() + 60  # no fixed pause: a slow machine reaps late
    while not _gone(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _gone(child), "the child outlived the interrupted bench"


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return True
    return "\nState:\tZ" in state  # a zombie waiting for its reaper is dead


def test_an_internal_error_is_one_line_exit_3_and_debug_shows_the_traceback(site, tmp_path):
    _, env = site
    (tmp_path / "bug.toml").write_text(scene_text("bug"))
    r = mixvi(["solve", str(tmp_path / "bug.toml"), "--out", str(tmp_path / "o")], env, tmp_path)
    assert r.returncode == 3 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "internal error" in lines[0] and "--debug" in lines[0]
    assert "a bug, not bad input" in lines[0]
    argv = ["--debug", "solve", str(tmp_path / "bug.toml"), "--out", str(tmp_path / "o")]
    r = mixvi(argv, env, tmp_path)
    assert r.returncode == 3 and "Traceback" in r.stderr and "RuntimeError" in r.stderr
    assert not (tmp_path / "o").exists()


def test_run_case_reports_a_dead_child_at_once(site, tmp_path, monkeypatch):
    """In-process: a killed child is seen by the liveness check, not by the timeout (the
    cause says SIGKILL; the mutation below, without the check, says timed out)."""
    import multiprocessing as mp

    from problems.commands import bench

    s, env = site
    monkeypatch.syspath_prepend(str(s))  # spawn children get the parent's sys.path
    (tmp_path / "kill.toml").write_text(scene_text("kill"))
    kind, cause = bench.run_case(
        mp.get_context("spawn"), str(tmp_path / "kill.toml"), 0, ["ssn"], 1e-10, timeout=600
    )
    assert kind == "error" and "SIGKILL" in cause


def test_mutation_without_the_liveness_check_only_the_timeout_ends_it(site, tmp_path, monkeypatch):
    import multiprocessing.process

    monkeypatch.setattr(multiprocessing.process.BaseProcess, "is_alive", lambda self: True)
    from problems.commands import bench

    monkeypatch.setattr(bench, "DEFAULT_TIMEOUT", 5)
    s, env = site
    monkeypatch.syspath_prepend(str(s))  # spawn children get the parent's sys.path
    (tmp_path / "kill.toml").write_text(scene_text("kill"))
    import multiprocessing as mp

    kind, cause = bench.run_case(
        mp.get_context("spawn"), str(tmp_path / "kill.toml"), 0, ["ssn"], 1e-10, timeout=5
    )
    assert kind == "error" and "timed out" in cause  # the crash is no longer recognised


def test_scenes_lists_broken_plugins_and_scenes_and_goes_on(site, tmp_path):
    _, env = site
    r = mixvi(["scenes"], env, tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr + r.stdout
    lines = r.stdout.splitlines()
    broken = [ln for ln in lines if "BROKEN" in ln]
    assert any("brokenplug" in ln and "broken on purpose" in ln for ln in broken), r.stdout
    assert any("garbled.toml" in ln for ln in broken), r.stdout
    # everything else is still listed
    assert any("fine.toml" in ln and "wobbly" in ln for ln in lines)
    assert any(ln.strip().startswith("paper_two_body") for ln in lines)
    assert any(ln.strip().startswith("signorini") for ln in lines)


# ------------------------------------------------------------------ --timeout counts the imports
# A module that sleeps when it is imported anywhere but in the process that wrote it (a bench
# child: the plug-in below), the way a plug-in with a slow or hanging import would.
SLEEPY = """
import multiprocessing, time
if multiprocessing.parent_process() is not None or {guard}:
    time.sleep(3600)
"""


def test_a_child_that_hangs_importing_its_plugin_is_a_timeout_row(tmp_path):
    """`mixvi bench --timeout 3`: the plug-in of the scene hangs while the child imports it
    (the parent imports it too, for the memory estimate, and must not hang): the row is a
    timeout and the table is written. No timed assertion: the subprocess bound only catches a
    wait without a limit."""
    site = tmp_path / "site"
    site.mkdir()
    plugin = WOBBLY.replace('NAME = "wobbly"', 'NAME = "sleepy"')
    (site / "sleepy.py").write_text(SLEEPY.format(guard="False") + plugin)
    info = site / "sleepy_test-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: sleepy-test\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[mixvi.plugins]\nsleepy = sleepy\n")
    scene = tmp_path / "sleepy.toml"
    scene.write_text(scene_text("none").replace('plugin = "wobbly"', 'plugin = "sleepy"'))
    env = {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}
    out = tmp_path / "bench.json"
    argv = ["bench", "--scenes", str(scene), "--levels", "0", "--timeout", "3", "--out", str(out)]
    r = mixvi(argv, env, tmp_path, timeout=600)
    assert r.returncode == 1 and "Traceback" not in r.stderr + r.stdout, r.stderr
    [row] = json.loads(out.read_text())["records"]
    assert "timed out after 3 s (--timeout)" in row["error"] and not row["converged"]
    assert "FAILED" in r.stdout


def test_run_case_times_out_a_child_hanging_in_its_start_up_imports(tmp_path, monkeypatch):
    """In-process: the child's target lives in a module that sleeps when the spawned
    interpreter imports it (unpickling the target, before any of mixvi's code runs in the
    child): `run_case` ends it at its timeout and says so."""
    import multiprocessing as mp

    from problems.commands import bench

    (tmp_path / "slow_start.py").write_text(
        SLEEPY.format(guard=f"__import__('os').getpid() != {os.getpid()}")
        + "\ndef child(*args):\n    args[4].put(('ok', []))\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))  # spawn children get the parent's sys.path
    import slow_start

    monkeypatch.setattr(bench, "_child", slow_start.child)
    kind, cause = bench.run_case(mp.get_context("spawn"), "obstacle", 0, ["ssn"], 1e-10, timeout=2)
    assert (kind, cause) == ("error", "timed out after 2 s (--timeout)")
