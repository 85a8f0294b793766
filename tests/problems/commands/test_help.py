"""A command line people read: every command listed with one line, every option with help,
a console summary without raw dicts."""

import argparse
import re

import pytest

from problems.commands import main as main_mod
from problems.commands.main import OWN_PARSERS, main, parser

COMMANDS = (
    "solve",
    "validate",
    "new",
    "schema",
    "scenes",
    "check",
    "figures",
    "study",
    "sweep",
    "bench",
    "extremes",
)


def test_help_lists_every_command_on_one_line(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    with pytest.raises(SystemExit) as ex:
        main(["--help"])
    assert ex.value.code == 0
    text = capsys.readouterr().out
    for name in COMMANDS:
        line = next((ln for ln in text.splitlines() if ln.split()[:1] == [name]), None)
        assert line is not None, f"{name} missing from mixvi --help"
        assert len(line.split()) > 2, f"{name} has no one-line description: {line!r}"
    assert set(COMMANDS) == set(parser()._subparsers._group_actions[0].choices)


def _undocumented(argv: list[str], monkeypatch) -> list[str]:
    """Options (besides -h) declared without help while `mixvi ARGV --help` runs."""
    missing = []
    real = argparse.ArgumentParser.add_argument

    def recording(self, *names, **kw):
        if not kw.get("help") and names and names[0] not in ("-h", "--help"):
            missing.append(f"{self.prog} {names[0]}")
        return real(self, *names, **kw)

    monkeypatch.setattr(argparse.ArgumentParser, "add_argument", recording)
    with pytest.raises(SystemExit):
        main_mod._dispatch([*argv, "--help"])
    return missing


@pytest.mark.parametrize("command", ["solve", *OWN_PARSERS])
def test_every_option_has_help(command, monkeypatch, capsys):
    assert _undocumented([command], monkeypatch) == []


def test_mutation_an_option_without_help_is_caught(monkeypatch, capsys):
    real = main_mod.add_force

    def bare(p):
        real(p)
        p.add_argument("--bare")

    monkeypatch.setattr(main_mod, "add_force", bare)
    assert any("--bare" in m for m in _undocumented(["solve"], monkeypatch))


def test_the_console_summary_is_a_table_and_a_contact_line(tmp_path, capsys):
    assert main(["solve", "rigid_foundation", "--level", "1", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "{" not in out and "}" not in out  # no raw dicts
    rows = re.findall(
        r"^\s+(\d)\s+([\d,]+)\s+(\d+)\s+([\d.]+)\s+([\d.e+-]+)\s+([\d.e+-]+)$", out, re.M
    )
    assert [r[0] for r in rows] == ["0", "1"]  # nested iteration: one row per level
    # each level's tolerance: the coarse one to 1e-6 (`pipeline.coarse_tol`), the fine to tol
    assert [float(r[4]) for r in rows] == [1e-6, 1e-10]
    assert all(float(r[5]) <= float(r[4]) for r in rows)
    contact = next(ln for ln in out.splitlines() if ln.strip().startswith("contact:"))
    assert re.search(r"stick \d+ \([\d.]+ m\), slip \d+ \([\d.]+ m\)", contact)
    assert re.search(r"force on the slave \(\S+, \S+\) N/m", contact)


def test_the_console_shows_the_electrical_fixed_point(tmp_path, capsys):
    """An electrical contact's outer loop is on the console, not only in summary.json: its
    steps, contraction, law defect and the potential jump agree with the summary."""
    import json

    out_dir = tmp_path / "o"
    assert main(["solve", "electrical_block", "--level", "1", "--out", str(out_dir)]) == 0
    out = capsys.readouterr().out
    el = json.loads((out_dir / "summary.json").read_text())["electrical"]
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("electrical contact"))
    assert f"{el['fixed_point']['iterations']} fixed-point steps" in line
    assert "converged" in line and "NOT" not in line
    assert f"{el['potential_gap_touching']:.6g} V" in line


def test_no_text_tells_to_install_mixvi_from_a_registry():
    """mixvi is not published: an extra is installed from the clone (pip install -e
    ".[dask]"), never `pip install mixvi[...]`."""
    from pathlib import Path

    root = Path(main_mod.__file__).resolve().parents[1]
    hits = [
        f"{p.relative_to(root)}: {ln.strip()}"
        for p in root.rglob("*.py")
        for ln in p.read_text().splitlines()
        if re.search(r"pip install mixvi\b", ln)
    ]
    assert not hits, hits
