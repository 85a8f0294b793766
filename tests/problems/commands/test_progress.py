"""Long work shows a progress bar on a terminal, and nothing of it in a pipe or a log file, nor
with TQDM_DISABLE set (tqdm's own switch: an explicit `disable=` in a call overrides it, so the
commands read it themselves, `problems.commands.progress`). Every command's bar is made there."""

import ast
import fcntl
import io
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

MIXVI = str(Path(sys.executable).parent / "mixvi")


def _on_a_terminal(argv, cwd, **env) -> str:
    """Run `mixvi argv` with stdout and stderr on a pseudo-terminal of 100 columns, as on a
    machine so fast that every step ends within tqdm's display interval (TQDM_MININTERVAL):
    the bar's last state must still be shown (it once was only when a step took > 0.1 s)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
    base = {k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"}  # whatever is set here
    env = {**base, "TQDM_MININTERVAL": "1000", **env}
    proc = subprocess.Popen([MIXVI, *argv], cwd=cwd, stdout=slave, stderr=slave, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=600) == 0
    os.close(master)
    return b"".join(chunks).decode(errors="replace")


STUDY = ["study", "obstacle", "--levels", "0..0", "--solvers", "ssn", "--tols", "1e-6"]
COMMANDS = [  # (argv, the bar's count), id
    pytest.param(["solve", "rigid_foundation", "--level", "2", "--out", "o"], "3/3",
                 id="solve: levels of the nested iteration"),
    pytest.param(["figures", "rigid_foundation", "--level", "0", "--out", "o"], "3/3",
                 id="figures: one solve per value"),
    pytest.param(["solve", "shear_strip_path", "--level", "0", "--out", "o"], "30/30",
                 id="solve: steps of a load path"),
    pytest.param([*STUDY, "--out", "o"], "1/1", id="study: one bar over the solves"),
]  # fmt: skip


@pytest.mark.parametrize(("argv", "bar"), COMMANDS)
def test_a_terminal_gets_a_progress_bar_and_a_pipe_does_not(tmp_path, argv, bar):
    (tmp_path / "tty").mkdir()
    (tmp_path / "pipe").mkdir()
    text = _on_a_terminal(argv, tmp_path / "tty")
    assert "%|" in text and bar in text
    run = subprocess.run([MIXVI, *argv], cwd=tmp_path / "pipe", capture_output=True, text=True)
    assert run.returncode == 0 and "%|" not in run.stderr and bar not in run.stderr


# TQDM_DISABLE is read by the one helper (test_the_helper_draws_only_on_a_terminal_...): one
# command in the CI tier (study, the quickest), every one in the slow tier
TQDM_CI = "study: one bar over the solves"


@pytest.mark.parametrize(
    ("argv", "bar"),
    [
        pytest.param(*p.values, id=p.id, marks=[pytest.mark.slow] * (p.id != TQDM_CI))
        for p in COMMANDS
    ],
)
def test_tqdm_disable_turns_the_bar_off_on_a_terminal(tmp_path, argv, bar):
    text = _on_a_terminal(argv, tmp_path, TQDM_DISABLE="1")
    assert "%|" not in text and f"| {bar} [" not in text


def test_every_bar_is_made_by_the_one_helper():
    """No command module but problems.commands.progress imports tqdm (a new bar made directly
    would skip TQDM_DISABLE or show in a pipe)."""
    root = Path(__file__).resolve().parents[3]
    users = []
    for path in sorted((root / "problems").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            module = node.module if isinstance(node, ast.ImportFrom) else None
            if "tqdm" in [*names, module] or str(module).startswith("tqdm."):
                users.append(path.relative_to(root).as_posix())
    assert users == ["problems/commands/progress.py"]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize(
    ("tty", "env", "shown", "drawn"),
    [
        (True, None, True, True),
        (True, "1", True, False),
        (True, "", True, True),  # set but empty: tqdm's reading, not disabled
        (False, None, True, False),
        (True, None, False, False),  # --no-progress
    ],
)
def test_the_helper_draws_only_on_a_terminal_without_tqdm_disable(
    monkeypatch, tty, env, shown, drawn
):
    from problems.commands import progress

    stderr = _Terminal() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", stderr)
    if env is None:
        monkeypatch.delenv("TQDM_DISABLE", raising=False)
    else:
        monkeypatch.setenv("TQDM_DISABLE", env)
    with progress.bar(total=2, shown=shown, desc="solving") as bar:
        bar.update(2)
        bar.refresh()
    assert ("2/2" in stderr.getvalue()) == drawn


def test_a_terminal_shows_the_newton_steps_of_the_level_being_solved(tmp_path):
    """Beside the bar over the levels: the level's Newton step, residual, active and slip rows
    and, on the iterative path, GMRES iterations so far; none of it in a pipe."""
    argv = ["solve", "rigid_foundation", "--level", "1", "--linear-solver", "amg", "--out", "o"]
    (tmp_path / "tty").mkdir()
    (tmp_path / "pipe").mkdir()
    text = _on_a_terminal(argv, tmp_path / "tty", TQDM_MININTERVAL="0")
    assert "L0 Newton 1" in text and "L1 Newton 1" in text
    assert "active" in text and "slip" in text and "GMRES" in text
    run = subprocess.run([MIXVI, *argv], cwd=tmp_path / "pipe", capture_output=True, text=True)
    assert run.returncode == 0 and "L1 Newton" not in run.stderr


def _steps_seen() -> tuple[list, object]:
    """(the on_step calls of a nested amg solve of rigid_foundation at level 2, its Run)."""
    from problems import pipeline

    seen: list[tuple[int, dict]] = []
    run = pipeline.solve(
        pipeline.load("rigid_foundation"),
        2,
        linear_solver="amg",
        on_step=lambda level, info: seen.append((level, info)),
    )
    return seen, run


def _check_steps(seen: list, run) -> None:
    """Every level reports each Newton step once when it is done, in order, the last with
    the level's residual; GMRES iterations grow within a level and match its Krylov total."""
    for rec in run.nested:
        done = [i for lev, i in seen if lev == rec["level"] and i["done"]]
        assert [i["step"] for i in done] == list(range(1, rec["iterations"] + 1))
        assert done[-1]["residual"] == pytest.approx(rec["residual"])
        its = [i["krylov_iterations"] for lev, i in seen if lev == rec["level"]]
        assert its == sorted(its) and its[-1] > 0
        assert all(i["active"] + i["slip"] <= run.model.vi.m for i in done)
    fine = [i["krylov_iterations"] for lev, i in seen if lev == 2 and i["done"]]
    assert fine[-1] == sum(run.solution.info["krylov_iterations"])
    assert any(not i["done"] for _, i in seen)  # GMRES iterations within a step


def test_the_pipeline_reports_every_newton_step_through_on_step():
    _check_steps(*_steps_seen())


def test_mutation_a_solver_that_never_calls_on_step_is_caught(monkeypatch):
    """ssn dropping its on_step (the callback never called) fails the check above."""
    from vi_core import ssn

    original = ssn.solve_ssn

    def deaf(vi, *args, on_step=None, **kw):
        return original(vi, *args, **kw)

    monkeypatch.setattr(ssn, "solve_ssn", deaf)
    seen, run = _steps_seen()
    with pytest.raises((AssertionError, IndexError)):
        _check_steps(seen, run)
