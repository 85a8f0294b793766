"""`mixvi solve SCENE --accuracy NUMBER` (problems.commands.adapt): options and scenes it
refuses before anything runs or is written (exit 2, the option, its value, what is allowed)."""

import pytest

from problems.commands.main import main


def _refused(capsys, argv: list[str]) -> str:
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "shown"),
    [
        (["--level", "2"], "--level = 2: not with --accuracy 0.3 (adaptive"),
        (["--cold"], "--cold = True: not with --accuracy 0.3 (adaptive"),
        (["--write-levels"], "--write-levels = True: not with --accuracy 0.3 (adaptive"),
        (["--solver", "admm"], "--solver = 'admm': one of auto, ssn, conic"),
    ],
)
def test_options_it_would_ignore_or_fail_on_are_refused(tmp_path, capsys, extra, shown):
    """Before: --level, --cold and --write-levels were ignored (exit 0, the run as without
    them), --solver admm failed after the table's header as an internal error (exit 3)."""
    out = tmp_path / "o"
    err = _refused(
        capsys, ["solve", "manufactured", "--accuracy", "0.3", *extra, "--out", str(out)]
    )
    assert shown in err
    assert not out.exists()


def test_a_load_path_scene_is_refused(tmp_path, capsys):
    """Before: shear_strip_path adapted the loads at t = 0 (all zero), 'reached' a relative
    estimate 6.8e-16 in one cycle and wrote a zero solution with exit 0."""
    out = tmp_path / "o"
    err = _refused(capsys, ["solve", "shear_strip_path", "--accuracy", "0.2", "--out", str(out)])
    assert "--accuracy = 0.2" in err and "[load_path]" in err and "fast, balanced, fine" in err
    assert not out.exists()
