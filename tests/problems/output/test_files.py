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

import pytest

from problems.errors import SceneError
from problems.output import files, signals
from problems.output.files import MARKER, output_file, output_folder


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
    assert sorted(files._files(out)) == ["new.vtu", "summary.json"]
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
    fd = os.open(out / files.LOCK, os.O_RDWR | os.O_CREAT)
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


def test_single_file_is_replaced_atomically_and_checked_first(tmp_path):
    f = tmp_path / "t.json"
    f.write_text("old")
    with output_file(f, "--json") as target:
        assert f.read_text() == "old"
        target.write("new")
    assert f.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]
    with pytest.raises(SceneError, match="folder"), output_file(tmp_path, "--json"):
        pass
    with pytest.raises(SceneError, match="regular file"), output_file("/dev/null", "--json"):
        pass
    link = tmp_path / "link.json"
    link.symlink_to(f)
    with output_file(link, "--json") as target:
        target.write("via link")
    assert link.is_symlink() and f.read_text() == "via link"


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
    assert sorted(files._files(out)) == marker["files"]
    assert (out / "summary.json").read_text() == "2"
    assert not [p for p in os.listdir(out) if p.startswith(files.STAGING)]


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
    monkeypatch.setattr(files, "first_foreign", lambda folder: None)
    with pytest.raises(CAUGHT):
        test_folder_with_foreign_files_is_refused_before_work(tmp_path, "notes.txt")


def test_mutation_commit_without_signal_deferral_is_caught(tmp_path, monkeypatch):
    import contextlib

    monkeypatch.setattr(files, "deferred", contextlib.nullcontext)
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
        tmp = self.path / f"{files.STAGING}leak"
        tmp.mkdir()
        try:
            yield tmp
            self._commit(tmp)
        finally:
            files.shutil.rmtree(tmp, ignore_errors=True)

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
    monkeypatch.setattr(files, "_prune", lambda root, rel: None)
    out = tmp_path / "out"
    run(out, {"summary.json": "{}", "levels/0/a.vtu": ""})
    run(out, {"summary.json": "{}"})
    assert (out / "levels" / "0").is_dir()
