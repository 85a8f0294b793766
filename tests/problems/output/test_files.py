"""Output folders and files: nothing of the user's is deleted, moved or replaced; a run is
committed whole (marker last) or not at all; claims are checked and locked before work.

Mutation tests at the end switch a safeguard off (ownership check, signal deferral of the
commit, stale-file bookkeeping) and assert that the property test catches it.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import stat
from pathlib import Path

import pytest

from problems.errors import SceneError
from problems.output import files, folder, paths, signals, single
from problems.output.files import Output, claim, output_folder
from problems.output.paths import MARKER


def tree(root) -> dict:
    """Every file and folder under `root`: relative path → bytes (None for folders) and mode."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            p = os.path.join(dirpath, d)
            out[os.path.relpath(p, root)] = (None, stat.S_IMODE(os.stat(p).st_mode))
        for f in filenames:
            p = os.path.join(dirpath, f)
            if os.path.islink(p):
                out[os.path.relpath(p, root)] = ("link", os.readlink(p))
                continue
            with open(p, "rb") as fh:
                out[os.path.relpath(p, root)] = (fh.read(), stat.S_IMODE(os.stat(p).st_mode))
    return out


def run(path, names: dict[str, str], overwrite=False) -> None:
    with output_folder(path, overwrite=overwrite, command="test") as folder:
        with folder.staging() as tmp:
            for name, text in names.items():
                (tmp / name).parent.mkdir(parents=True, exist_ok=True)
                (tmp / name).write_text(text)


def test_new_folder_gets_files_and_a_marker_written_last(tmp_path):
    out = tmp_path / "a" / "b"
    run(out, {"summary.json": "{}", "x.vtu": "v"})
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "summary.json", "x.vtu"]
    marker = json.loads((out / MARKER).read_text())
    assert marker["complete"] and marker["files"] == ["summary.json", "x.vtu"]
    assert marker["command"] == "test" and marker["mixvi"] and marker["time"]


def test_folders_and_files_get_the_users_umask(tmp_path):
    old = os.umask(0o022)
    try:
        run(tmp_path / "u", {"f.json": "1"})
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "u").stat().st_mode) == 0o755
    assert stat.S_IMODE((tmp_path / "u" / "f.json").stat().st_mode) == 0o644


@pytest.mark.parametrize("user_file", ["notes.txt", "scene.toml", "summary.json.bak", "sub/x.png"])
def test_folder_with_foreign_files_is_refused_before_work(tmp_path, user_file):
    out = tmp_path / "o"
    (out / user_file).parent.mkdir(parents=True, exist_ok=True)
    (out / user_file).write_text("mine")
    before = tree(tmp_path)
    with pytest.raises(SceneError) as err:
        run(out, {"summary.json": "{}"})
    assert "--out" in str(err.value) and user_file in str(err.value) and str(out) in str(err.value)
    assert tree(tmp_path) == before


def test_overwrite_writes_beside_foreign_files_and_deletes_none(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "scene.toml").write_text("mine")
    run(out, {"summary.json": "1", "a.png": "a"}, overwrite=True)
    run(out, {"summary.json": "2"}, overwrite=True)  # a.png was mixvi's: removed; scene kept
    assert (out / "scene.toml").read_text() == "mine"
    assert (out / "summary.json").read_text() == "2" and not (out / "a.png").exists()


def test_second_run_removes_only_its_predecessors_files(tmp_path):
    out = tmp_path / "o"
    run(out, {"summary.json": "1", "old.vtu": "v", "sub/deep.png": "d"})
    run(out, {"summary.json": "2", "new.vtu": "w"})
    assert sorted(paths.files_under(out)) == ["new.vtu", "summary.json"]
    assert json.loads((out / MARKER).read_text())["files"] == ["new.vtu", "summary.json"]


def test_unmarked_folder_of_an_earlier_version_counts_as_mixvis(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    for f in ("summary.json", "block.vtu", "potential.png"):
        (out / f).write_text("old")
    run(out, {"summary.json": "new"})
    assert (out / "summary.json").read_text() == "new"
    assert (out / "block.vtu").read_text() == "old"  # an earlier version's: kept, never deleted
    assert json.loads((out / MARKER).read_text())["earlier"] == ["block.vtu", "potential.png"]
    run(out, {"summary.json": "newer"})  # and still counts as mixvi's on the next run
    assert (out / "block.vtu").read_text() == "old" and (out / "potential.png").exists()


def test_an_error_while_writing_leaves_the_previous_run_untouched(tmp_path):
    out = tmp_path / "o"
    run(out, {"summary.json": "1", "a.png": "a"})
    before = tree(tmp_path)
    with pytest.raises(RuntimeError), output_folder(out, command="t") as folder:
        with folder.staging() as tmp:
            (tmp / "summary.json").write_text("2")
            raise RuntimeError("plot failed")
    assert tree(tmp_path) == before


def test_created_folders_are_removed_when_nothing_was_written(tmp_path):
    with pytest.raises(RuntimeError), output_folder(tmp_path / "x" / "y" / "z"):
        raise RuntimeError("solve failed")
    assert list(tmp_path.iterdir()) == []


def test_a_second_run_into_a_locked_folder_is_refused(tmp_path):
    out = tmp_path / "o"
    with output_folder(out, command="first"):
        with pytest.raises(SceneError, match="locked by process"):
            with output_folder(out, command="second"):
                pass
    with output_folder(out):  # released: usable again
        pass


def test_a_lock_held_by_another_process_is_respected(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    fd = os.open(out / paths.LOCK, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        with pytest.raises(SceneError, match="locked"), output_folder(out):
            pass
    finally:
        os.close(fd)


def _under_file(t):
    (t / "f").write_text("x")
    return t / "f" / "sub"


def _is_file(t):
    (t / "f").write_text("x")
    return t / "f"


def _dangling(t):
    (t / "dangling").symlink_to(t / "nowhere")
    return t / "dangling" / "o"


@pytest.mark.parametrize(
    "make, allowed",
    [
        (_under_file, "is a file"),
        (_is_file, "is a file"),
        (lambda t: t / "/proc/mixvi-test-out", "create"),
        (lambda t: t / "/sys/mixvi-test-out", "create"),
        (_dangling, "broken"),
    ],
)
def test_impossible_targets_are_refused_before_work(tmp_path, make, allowed):
    target = make(tmp_path)
    before = tree(tmp_path)
    with pytest.raises(SceneError) as err, output_folder(target):
        raise AssertionError("the body must not run")
    assert allowed in str(err.value) and "--out" in str(err.value)
    assert tree(tmp_path) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_parent_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(SceneError, match="permission"), output_folder(ro / "o"):
            pass
    finally:
        ro.chmod(0o755)


def write_one(path, data, option="--json", overwrite=False, kind="json") -> None:
    with claim([Output(path, option, kind)], overwrite=overwrite) as run:
        run.file(option).write(data)


def test_single_file_is_signed_replaced_atomically_and_checked_first(tmp_path):
    f = tmp_path / "t.json"
    write_one(f, {"a": 1})
    data = json.loads(f.read_text())
    assert list(data) == ["written_by", "a"] and data["written_by"].startswith("mixvi ")
    assert single.written_by_mixvi(f)
    with claim([Output(f, "--json", "json")]) as run:  # mixvi's: replaced without --overwrite
        run.file("--json").write({"a": 2})
        assert json.loads(f.read_text())["a"] == 1  # staged until the commit
    assert json.loads(f.read_text())["a"] == 2 and sorted(os.listdir(tmp_path)) == ["t.json"]
    with pytest.raises(SceneError, match="folder"):
        write_one(tmp_path, {})
    with pytest.raises(SceneError, match="regular file"):
        write_one("/dev/null", {})
    link = tmp_path / "link.json"
    link.symlink_to(f)
    write_one(link, {"via": "link"})
    assert link.is_symlink() and json.loads(f.read_text())["via"] == "link"


def test_svg_is_signed_after_its_xml_declaration(tmp_path):
    f = tmp_path / "f.svg"
    write_one(f, '<?xml version="1.0"?>\n<svg/>\n', "--figure", kind="svg")
    text = f.read_text()
    assert text.startswith('<?xml version="1.0"?>\n<!-- written_by: mixvi ')
    assert text.endswith("<svg/>\n") and single.written_by_mixvi(f)


@pytest.mark.parametrize("content", [b"mine", b'{"written_by": "someone else"}', b"", b"<svg/>"])
def test_a_file_mixvi_did_not_write_is_refused_unless_overwrite(tmp_path, content):
    f = tmp_path / "r.json"
    f.write_bytes(content)
    before = tree(tmp_path)
    with pytest.raises(SceneError) as err:
        write_one(f, {"a": 1})
    assert "--json" in str(err.value) and "--overwrite" in str(err.value)
    assert tree(tmp_path) == before
    write_one(f, {"a": 1}, overwrite=True)
    assert json.loads(f.read_text())["a"] == 1


def _scene(t):
    (t / "mesh.msh").write_text("mesh")
    (t / "s.toml").write_text("scene")
    return [("the scene file", t / "s.toml"), ("the file of geometry.mesh", t / "mesh.msh")]


@pytest.mark.parametrize(
    "which", ["s.toml", "mesh.msh", "link.toml", "hard.toml", "./sub/../s.toml"]
)
@pytest.mark.parametrize("kind", ["json", "folder"])
def test_an_input_is_never_an_output_even_with_overwrite(tmp_path, which, kind):
    inputs = _scene(tmp_path)
    (tmp_path / "link.toml").symlink_to(tmp_path / "s.toml")
    os.link(tmp_path / "s.toml", tmp_path / "hard.toml")
    (tmp_path / "sub").mkdir()
    before = tree(tmp_path)
    with pytest.raises(SceneError) as err:
        with claim([Output(tmp_path / which, "--out", kind)], inputs, overwrite=True) as run:
            if kind == "json":
                run.file("--out").write({})
    assert "not an input of this run" in str(err.value) and "--out" in str(err.value)
    assert tree(tmp_path) == before


def test_an_input_inside_an_output_folder_is_never_replaced(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "summary.json").write_text("the user's scene, oddly named")
    inputs = [("the scene file", out / "summary.json")]
    before = tree(tmp_path)
    with pytest.raises(SceneError, match="does not replace an input"):
        with output_folder(out, overwrite=True, inputs=inputs) as folder:
            with folder.staging() as tmp:
                (tmp / "summary.json").write_text("{}")
    assert tree(tmp_path) == before


@pytest.mark.parametrize(
    "a, b, says",
    [
        ("r.json", "r.json", "the same path as"),
        ("r.json", "./x/../r.json", "the same path as"),
        ("d", "d/r.svg", "inside"),
        ("d/r.svg", "d", "a folder holding"),
    ],
)
def test_two_outputs_of_one_run_never_share_a_path(tmp_path, a, b, says):
    (tmp_path / "x").mkdir()
    outputs = [Output(tmp_path / a, "--out", "json"), Output(tmp_path / b, "--figure", "svg")]
    before = tree(tmp_path)
    with pytest.raises(SceneError) as err, claim(outputs):
        raise AssertionError("the body must not run")
    assert says in str(err.value) and "--figure" in str(err.value)
    assert tree(tmp_path) == before


def test_the_single_files_of_a_run_are_committed_together_or_not_at_all(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.svg"
    write_one(a, {"v": 1})
    before = tree(tmp_path)
    outputs = [Output(a, "--out", "json"), Output(b, "--figure", "svg")]
    with pytest.raises(RuntimeError), claim(outputs) as run:
        run.file("--out").write({"v": 2})
        raise RuntimeError("the figure failed")
    assert tree(tmp_path) == before
    with claim(outputs) as run:
        run.file("--out").write({"v": 2})
        run.file("--figure").write("<svg/>")
    assert json.loads(a.read_text())["v"] == 2 and b.read_text().endswith("<svg/>")
    assert sorted(os.listdir(tmp_path)) == ["a.json", "b.svg"]


def test_signal_during_the_commit_is_deferred_until_it_is_complete(tmp_path, monkeypatch):
    out = tmp_path / "o"
    run(out, {"summary.json": "1", "a.png": "a", "b.png": "b"})
    signals.install()
    real = os.replace
    calls = []

    def replace_then_signal(a, b):
        real(a, b)
        calls.append(b)
        if len(calls) == 2:  # in the middle of the commit (marker, then the files)
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(files.os, "replace", replace_then_signal)
    with pytest.raises(signals.Interrupted):
        run(out, {"summary.json": "2", "a.png": "A", "c.png": "C"})
    marker = json.loads((out / MARKER).read_text())
    assert marker["complete"] and marker["files"] == ["a.png", "c.png", "summary.json"]
    assert sorted(paths.files_under(out)) == marker["files"]
    assert (out / "summary.json").read_text() == "2"
    assert not [p for p in os.listdir(out) if p.startswith(paths.STAGING)]


def timeless(root) -> dict:
    """`tree(root)` with the marker's time stamp taken out."""
    out = tree(root)
    for name, (data, mode) in out.items():
        if name.endswith(MARKER):
            marker = json.loads(data)
            marker.pop("time")
            out[name] = (marker, mode)
    return out


@pytest.mark.parametrize("call", ["mkdir", "open"])
def test_a_signal_right_after_any_creation_leaves_nothing_behind(tmp_path, monkeypatch, call):
    """SIGINT delivered right after the k-th folder or file creation of a run (output folder,
    lock, probe, staging folder, temporary file), for every k: the run is interrupted and the
    tree is as before (the run's own folder gone again, the previous run byte-identical), or,
    when the signal came during the commit, as after a complete run."""
    signals.install()
    patched = (files.os, "open") if call == "open" else (files.Path, "mkdir")
    real = getattr(*patched)
    for previous in (False, True):
        base, root, clean = (tmp_path / f"{name}{previous}" for name in ("base", "root", "clean"))
        base.mkdir()
        if previous:
            run(base / "o", {"summary.json": "1", "a.png": "a"})
        shutil.copytree(base, clean)
        run(clean / "o", {"summary.json": "2", "b.png": "b"})
        before, after = timeless(base), timeless(clean)
        for k in range(1, 50):
            shutil.rmtree(root, ignore_errors=True)
            shutil.copytree(base, root)
            count = [0]

            def then_signal(*args, count=count, k=k, **kw):
                result = real(*args, **kw)
                count[0] += 1
                if count[0] == k:
                    os.kill(os.getpid(), signal.SIGINT)
                return result

            with monkeypatch.context() as m:
                m.setattr(*patched, then_signal)
                try:
                    run(root / "o", {"summary.json": "2", "b.png": "b"})
                except signals.Interrupted:
                    assert timeless(root) in (before, after), (call, previous, k)
                    continue
            assert count[0] < k  # no signal was sent: every creation point was tried
            break
        else:
            pytest.fail("more than 49 creations in one run")


# ------------------------------------------------------------------ mutation tests
CAUGHT = (AssertionError, pytest.fail.Exception)


def test_mutation_no_ownership_check_is_caught(tmp_path, monkeypatch):
    monkeypatch.setattr(folder, "first_foreign", lambda folder: None)
    with pytest.raises(CAUGHT):
        test_folder_with_foreign_files_is_refused_before_work(tmp_path, "notes.txt")


def test_mutation_commit_without_signal_deferral_is_caught(tmp_path, monkeypatch):
    import contextlib

    monkeypatch.setattr(folder, "deferred", contextlib.nullcontext)
    with pytest.raises(CAUGHT):
        test_signal_during_the_commit_is_deferred_until_it_is_complete(tmp_path, monkeypatch)


def test_mutation_stale_files_not_removed_is_caught(tmp_path, monkeypatch):
    real = files.OutputFolder._commit

    def keep_previous(self, tmp):
        self.previous = []
        real(self, tmp)

    monkeypatch.setattr(files.OutputFolder, "_commit", keep_previous)
    with pytest.raises(CAUGHT):
        test_second_run_removes_only_its_predecessors_files(tmp_path)


def test_mutation_staging_mkdir_outside_the_cleanup_is_caught(tmp_path, monkeypatch):
    """The staging folder made before the try whose finally removes it (the old code): a
    signal right after its mkdir leaves it behind."""
    import contextlib

    @contextlib.contextmanager
    def leaky_staging(self):
        tmp = self.path / f"{paths.STAGING}leak"
        tmp.mkdir()
        try:
            yield tmp
            self._commit(tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    monkeypatch.setattr(files.OutputFolder, "staging", leaky_staging)
    with pytest.raises(CAUGHT):
        test_a_signal_right_after_any_creation_leaves_nothing_behind(tmp_path, monkeypatch, "mkdir")


def test_a_later_run_removes_the_subfolders_it_emptied_and_keeps_the_rest(tmp_path):
    out = tmp_path / "out"
    run(out, {n: n for n in ["summary.json", "levels/0/a.vtu", "levels/1/a.vtu", "levels/1/b"]})
    (out / "levels" / "1" / "mine.txt").write_text("the user's")
    run(out, {"summary.json": "{}"}, overwrite=True)
    assert not (out / "levels" / "0").exists()  # emptied by this run: gone
    assert (out / "levels" / "1" / "mine.txt").read_text() == "the user's"  # kept, and its folder
    assert not (out / "levels" / "1" / "a.vtu").exists()


def test_mutation_without_pruning_empty_subfolders_stay(tmp_path, monkeypatch):
    monkeypatch.setattr(folder, "prune", lambda root, rel: None)
    out = tmp_path / "out"
    run(out, {"summary.json": "{}", "levels/0/a.vtu": ""})
    run(out, {"summary.json": "{}"})
    assert (out / "levels" / "0").is_dir()


# ------------------------------------------------------------------ a killed run's leftovers
KILLED = """
import os, signal, sys
from problems.output.files import Output, claim
with claim([Output(sys.argv[1], "--out", sys.argv[2])], overwrite=True) as run:
    if sys.argv[2] == "folder":
        with run.folder("--out").staging() as tmp:
            (tmp / "summary.json").write_text("half")
            os.kill(os.getpid(), signal.SIGKILL)
    run.file("--out").write({"half": True})
    os.kill(os.getpid(), signal.SIGKILL)
"""


def killed_run(target, kind: str) -> None:
    """A process that claims `target`, stages a file and is killed by SIGKILL (no clean-up)."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", KILLED, str(target), kind], capture_output=True)
    assert r.returncode == -signal.SIGKILL, r.stderr


def test_a_rerun_after_a_sigkill_clears_the_stale_lock_and_staging_and_says_so(tmp_path, capsys):
    out = tmp_path / "o"
    run(out, {"summary.json": "1", "a.png": "a"})
    (out / "notes.txt").write_text("the user's")
    killed_run(out, "folder")
    left = sorted(os.listdir(out))
    assert paths.LOCK in left and any(p.startswith(paths.STAGING) for p in left)  # the state
    capsys.readouterr()
    run(out, {"summary.json": "2"}, overwrite=True)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no longer running" in err[0] and "lock" in err[0], err
    assert "staged files" in err[0] and str(out) in err[0]
    assert sorted(os.listdir(out)) == [MARKER, "notes.txt", "summary.json"]
    assert (out / "notes.txt").read_text() == "the user's"
    run(out, {"summary.json": "3"}, overwrite=True)  # nothing stale any more: no note
    assert capsys.readouterr().err == ""


def test_a_rerun_after_a_sigkill_clears_a_single_files_temporary(tmp_path, capsys):
    f = tmp_path / "b.json"
    write_one(f, {"v": 1}, option="--out")
    (tmp_path / "mine.json").write_text("the user's")
    before = tree(tmp_path)
    killed_run(f, "json")
    assert len(os.listdir(tmp_path)) == 3 and tree(tmp_path) != before  # its temporary file
    capsys.readouterr()
    with claim([Output(f, "--out", "json")]):  # claimed, nothing written: as before
        pass
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no longer running" in err[0], err
    assert tree(tmp_path) == before


def test_a_live_runs_staging_is_never_cleared(tmp_path):
    """A staging entry of a process that runs (here: this one) stays; only dead ones go."""
    (tmp_path / f"{paths.STAGING}{os.getpid()}-0123abcd").mkdir()
    (tmp_path / f"{paths.STAGING}999999999-0123abcd").mkdir()  # no such process
    (tmp_path / ".mixvi-tmp-notes").write_text("not a name mixvi gives")
    assert paths.clear_stale(tmp_path) == [999999999]
    assert set(os.listdir(tmp_path)) == {
        ".mixvi-tmp-notes",
        f"{paths.STAGING}{os.getpid()}-0123abcd",
    }


def test_mutation_no_stale_recognition_is_caught(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(folder, "clear_stale", lambda where, name=None: [])
    monkeypatch.setattr(single, "clear_stale", lambda where, name=None: [])
    with pytest.raises(CAUGHT):
        test_a_rerun_after_a_sigkill_clears_the_stale_lock_and_staging_and_says_so(tmp_path, capsys)


def test_mutation_no_input_check_is_caught(tmp_path, monkeypatch):
    monkeypatch.setattr(files, "identity", lambda path: None)
    monkeypatch.setattr(files, "_real", lambda path: Path(os.path.abspath(path)) / "x")
    with pytest.raises(CAUGHT):
        test_an_input_is_never_an_output_even_with_overwrite(tmp_path, "s.toml", "json")


def test_mutation_stale_lock_not_reported_is_caught(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(folder, "_stale_note", lambda *a: None)
    with pytest.raises(CAUGHT):
        test_a_rerun_after_a_sigkill_clears_the_stale_lock_and_staging_and_says_so(tmp_path, capsys)
