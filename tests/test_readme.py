"""The README's commands, run as written: "Your own problem in four steps" (template → gmsh
mesh → validate → solve) in an empty folder, its Python API block, and its test command against
what CI runs (.ci/run). A README whose commands break fails here; the mutation tests change a
command in a copy of the README and see the run fail.

The `mixvi` lines run in this process through `problems.commands.main.main` (the console
script's own entry, the same parser and commands; one import of NumPy/SciPy instead of one per
command keeps the test within a few seconds); every other line runs in bash with this venv's
`bin/` first on PATH. Without gmsh the mesh step is left out and the template's own mesh is
validated and solved."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from problems.commands.main import main
from tests import optional

ROOT = Path(__file__).resolve().parents[1]
FOUR_STEPS = "## Your own problem in four steps"


def section(text: str, heading: str) -> str:
    """The text of one `##` section of a Markdown file (its heading line excluded)."""
    start = text.index(heading + "\n") + len(heading) + 1
    end = text.find("\n## ", start)
    return text[start : end if end >= 0 else len(text)]


def fenced(text: str) -> list[tuple[str, str]]:
    """The fenced code blocks of `text` as (language, body)."""
    return [(m[1], m[2]) for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.M | re.S)]


def indented(text: str) -> list[str]:
    """The lines of the 4-space indented code blocks of `text`, without their indentation."""
    return [line[4:] for line in text.splitlines() if line.startswith("    ") and line.strip()]


def commands(body: str) -> list[str]:
    """The commands of a bash block: one per line, `\\` continuations joined."""
    return [c.strip() for c in body.replace("\\\n", " ").splitlines() if c.strip()]


def four_steps(readme: str) -> tuple[dict[str, str], list[list[str]]]:
    """The files the section writes (python blocks whose first line is `# NAME.py`) and its
    bash blocks, each a list of commands, in order."""
    files, blocks = {}, []
    for lang, body in fenced(section(readme, FOUR_STEPS)):
        if lang == "python":
            name = re.match(r"# (\S+\.py)\n", body)
            assert name, f"a python block of the four steps without a '# NAME.py' line:\n{body}"
            files[name[1]] = body
        elif lang == "bash":
            blocks.append(commands(body))
    return files, blocks


def run_four_steps(readme: str, cwd: Path, gmsh: bool) -> list[str]:
    """Run the four steps of `readme` in `cwd` (the current directory must be `cwd`); the
    commands run, in order. AssertionError naming the command when one fails."""
    files, blocks = four_steps(readme)
    for name, body in files.items():
        (cwd / name).write_text(body)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    env["MPLBACKEND"] = "Agg"
    ran = []
    for block in blocks:
        meshing = any(f"python {name}" in c for c in block for name in files)
        if meshing and not gmsh:
            continue
        for command in block:
            if command.startswith("mixvi "):
                try:
                    status = main(shlex.split(command)[1:])
                except SystemExit as stop:  # argparse's refusal of an option
                    status = stop.code
                detail = ""
            else:
                r = subprocess.run(
                    ["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True
                )
                status, detail = r.returncode, r.stdout + r.stderr
            assert status == 0, f"README command failed (exit {status}): {command}\n{detail}"
            ran.append(command)
    return ran


def _gmsh() -> bool:
    return optional.has_gmsh()


def test_the_four_steps_run_as_written(tmp_path, monkeypatch):
    """template → mesh with physical groups (gmsh) → validate → solve, as the README says."""
    monkeypatch.chdir(tmp_path)
    ran = run_four_steps((ROOT / "README.md").read_text(), tmp_path, _gmsh())
    assert [c.split()[:2] for c in ran if c.startswith("mixvi")] == [
        ["mixvi", "new"],
        ["mixvi", "validate"],
        ["mixvi", "solve"],
    ]
    if _gmsh():  # the solve read the new mesh, not the template's
        assert 'mesh = "part.msh"' in (tmp_path / "part.toml").read_text()
        assert (tmp_path / "part.msh").exists()
    out = tmp_path / "out" / "part"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is True
    assert (out / "results.pvd").exists() and (out / "contact.csv").exists()


def test_a_broken_first_step_fails_the_run(tmp_path, monkeypatch):
    """Mutation: a misspelt template name in a copy of the README stops the run at step 1."""
    monkeypatch.chdir(tmp_path)
    readme = (ROOT / "README.md").read_text()
    assert "mixvi new plate_with_hole part.toml" in readme
    broken = readme.replace("mixvi new plate_with_hole", "mixvi new plate_with_holes")
    with pytest.raises(AssertionError, match="mixvi new plate_with_holes"):
        run_four_steps(broken, tmp_path, _gmsh())


@pytest.mark.parametrize(
    "old, new, failing",
    [
        ('name="hole"', 'name="holes"', "mixvi validate"),  # the group the scene names
        ("mixvi solve part.toml --level 0", "mixvi solve part.toml --levle 0", "mixvi solve"),
        ('|mesh = "part.msh"|', '|mesh = "prt.msh"|', "mixvi validate"),
    ],
)
def test_a_broken_command_fails_the_run(tmp_path, monkeypatch, old, new, failing):
    """Mutations: a wrong group name in the mesh script, a misspelt option, a scene pointed at
    a mesh that is not there; each must fail the step that meets it."""
    if not _gmsh():
        pytest.skip("gmsh not installed: the mesh step is not run")
    monkeypatch.chdir(tmp_path)
    readme = (ROOT / "README.md").read_text()
    assert old in section(readme, FOUR_STEPS)
    with pytest.raises(AssertionError, match=failing):
        run_four_steps(readme.replace(old, new), tmp_path, gmsh=True)


def test_the_api_block_runs(tmp_path, monkeypatch, capsys):
    """The README's Python API block, executed as written."""
    monkeypatch.chdir(tmp_path)
    (lang, body), *_ = fenced(section((ROOT / "README.md").read_text(), "## Python API"))
    assert lang == "python"
    exec(compile(body, "README.md (Python API)", "exec"), {})
    assert capsys.readouterr().out.split()[:1] == ["True"]  # converged
    assert list(tmp_path.iterdir()) == []  # nothing written


def ci_mismatch(readme: str, ci_run: str) -> str | None:
    """None if the README's test command is exactly .ci/run's first test command (the second
    runs the petsc engine's tests once .ci/install_petsc is done), else what differs."""
    mine = [c for c in indented(section(readme, "## Two commands")) if "pytest" in c]
    ci = [c for c in ci_run.splitlines() if "pytest" in c and not c.lstrip().startswith("#")]
    if len(mine) != 1 or not ci:
        return f"expected one test command in the README, {mine}, and one in .ci/run, {ci}"
    return None if mine[0] == ci[0] else f"README: {mine[0]}\n.ci/run: {ci[0]}"


def test_the_readme_test_command_is_what_ci_runs():
    readme, ci = (ROOT / "README.md").read_text(), (ROOT / ".ci" / "run").read_text()
    assert ci_mismatch(readme, ci) is None, ci_mismatch(readme, ci)


def test_a_changed_test_command_is_a_mismatch():
    """Mutation: the README's test command changed in a copy (a dropped lint) is caught."""
    readme, ci = (ROOT / "README.md").read_text(), (ROOT / ".ci" / "run").read_text()
    changed = readme.replace(" && .venv/bin/ruff format --check .", "", 1)
    assert changed != readme
    assert ci_mismatch(changed, ci) is not None


def test_the_readme_names_no_commit_or_issue():
    """A front door, not a lab notebook: no commit hashes, no issue numbers."""
    readme = (ROOT / "README.md").read_text()
    assert not re.findall(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b", readme)
    assert not re.findall(r"\bissues? \d+|#\d+\b", readme, re.I)
    assert len(readme.splitlines()) <= 250


def broken_links(readme: str, root: Path) -> list[str]:
    """The README's relative links and images whose file is not in the repository."""
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    return [t for t in targets if "://" not in t and not (root / t).exists()]


def test_the_readme_links_resolve():
    assert broken_links((ROOT / "README.md").read_text(), ROOT) == []


def test_a_link_to_a_missing_page_is_found():
    """Mutation: a link to a page that is not there."""
    readme = (ROOT / "README.md").read_text().replace("docs/tutorials/sweep.md", "docs/sweep.md")
    assert broken_links(readme, ROOT) == ["docs/sweep.md"]
