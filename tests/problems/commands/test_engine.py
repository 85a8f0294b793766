"""`mpiexec -n P mixvi solve SCENE --engine petsc`: output written once (rank 0), the serial
command's summary.json fields and exit statuses, bad input refused on every rank without a
hang, a rank killed mid-solve ending the run with nothing written."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from tests.vi_core.petsc.helpers import mixvi, mpiexec, need_petsc

pytestmark = pytest.mark.mpi  # .ci/run runs these after .ci/install_petsc

SCENE = "manufactured"


def summary(folder: Path) -> dict:
    return json.loads((folder / "summary.json").read_text())


@pytest.mark.slow
def test_same_files_and_summary_fields_as_serial(tmp_path):
    need_petsc()
    serial = subprocess.run(
        [mixvi(), "solve", SCENE, "--level", "1", "--out", str(tmp_path / "serial")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert serial.returncode == 0, serial.stderr
    par = mpiexec(
        2,
        [
            mixvi(),
            "solve",
            SCENE,
            "--level",
            "1",
            "--engine",
            "petsc",
            "--out",
            str(tmp_path / "petsc"),
        ],
    )
    assert par.returncode == 0, par.stderr[-3000:]
    assert par.stdout.count("wrote ") == 1  # rank 0 alone reports (and writes)
    a, b = summary(tmp_path / "serial"), summary(tmp_path / "petsc")
    assert set(a) == set(b)
    assert sorted(p.name for p in (tmp_path / "serial").iterdir()) == sorted(
        p.name for p in (tmp_path / "petsc").iterdir()
    )
    assert b["solver_info"]["engine"] == "petsc" and b["solver_info"]["ranks"] == 2
    assert abs(a["residual"] - b["residual"]) <= 1e-8 or b["residual"] <= 1e-10


def each_rank(argv: list[str]) -> list[str]:
    """`argv` run on each rank by a shell that prints the rank's own exit status to stderr
    ("rank R: S") and exits 0: mpiexec ends the job at the first non-zero status, which can
    end a slower rank before it says why (a refusal before any collective call: seen in CI),
    and its own status does not tell the ranks apart."""
    return ["sh", "-c", '"$@"; echo "rank $OMPI_COMM_WORLD_RANK: $?" >&2', "sh", *argv]


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--level", "99"], "--level"),  # argparse, on every rank
        pytest.param(
            ["--set", "contact.g=-1"], "contact.g", marks=pytest.mark.slow
        ),  # the scene's validation, on every rank
    ],
)
def test_bad_input_refused_on_every_rank(tmp_path, argv, says):
    need_petsc()
    argv = [mixvi(), "solve", SCENE, "--engine", "petsc", "--out", str(tmp_path / "o"), *argv]
    done = mpiexec(2, each_rank(argv), timeout=120)
    assert "rank 0: 2" in done.stderr and "rank 1: 2" in done.stderr, done.stderr[-2000:]
    # each rank says why (mpiexec may interleave the two ranks' lines)
    assert len(re.findall(r"mixvi( solve)?: error:", done.stderr)) == 2, done.stderr
    assert done.stderr.count(says) >= 2, done.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_output_refused_on_rank_0_ends_every_rank(tmp_path):
    """--out is a user's file: rank 0 refuses it, the others end too (no hang), nothing
    written, the file untouched."""
    need_petsc()
    mine = tmp_path / "notes.txt"
    mine.write_text("mine")
    done = mpiexec(
        2, [mixvi(), "solve", SCENE, "--engine", "petsc", "--out", str(mine)], timeout=120
    )
    assert done.returncode == 2, done.stderr
    assert "refused on rank 0" in done.stderr
    assert mine.read_text() == "mine"


def earlier_run(tmp_path: Path) -> tuple[Path, dict[str, bytes]]:
    """(the output folder of a serial solve of SCENE at level 0, its files' bytes by name):
    what a failed or interrupted run into the same folder must leave as it was."""
    out = tmp_path / "o"
    first = subprocess.run(
        [mixvi(), "solve", SCENE, "--level", "0", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert first.returncode == 0, first.stderr
    return out, {p.name: p.read_bytes() for p in out.iterdir()}


def _rank_pid(launcher: int, rank: int) -> int | None:
    """The pid of MPI rank `rank` among the descendants of `launcher` (its environment)."""
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            env = (p / "environ").read_bytes().split(b"\0")
        except OSError:
            continue
        if (
            f"OMPI_COMM_WORLD_RANK={rank}".encode() in env
            and b"MIXVI_KILL_TEST=" + str(launcher).encode() in env
        ):
            return int(p.name)
    return None


def _started_rank(tag: str, rank: int, seconds: float = 60) -> int:
    """The pid of rank `rank` of the run tagged `tag` once it has started; the test fails if
    it has not within `seconds`."""
    t0 = time.monotonic()
    while (pid := _rank_pid(int(tag), rank)) is None:
        assert time.monotonic() - t0 < seconds, f"rank {rank} not started in {seconds:.0f} s"
        time.sleep(0.2)
    return pid


@pytest.mark.slow
def test_rank_killed_mid_solve_ends_the_run(tmp_path):
    """SIGKILL to rank 1 while the ranks solve: mpiexec ends every rank, says which one died,
    and the output folder holds no half-written results."""
    need_petsc()
    out = tmp_path / "o"
    tag = str(os.getpid())
    run = mpiexec(
        2,
        [
            mixvi(),
            "solve",
            "paper_two_body",
            "--level",
            "4",
            "--engine",
            "petsc",
            "--out",
            str(out),
        ],
        popen=True,
        env={"MIXVI_KILL_TEST": tag},
    )
    try:
        pid, t0 = _started_rank(tag, 1), time.monotonic()
        while not out.exists() and run.poll() is None and time.monotonic() - t0 < 120:
            time.sleep(0.2)  # rank 0 has claimed the folder: the solve runs
        time.sleep(1.0)
        os.kill(pid, signal.SIGKILL)
        stdout, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode != 0
    # mpiexec names the rank and the signal; rank 0 (SIGTERM from mpiexec) says it stopped
    assert "rank 1" in stderr and "signal 9" in stderr, stderr[-2000:]
    assert not (out / "summary.json").exists()
    assert not any(p.name.startswith(".mixvi-tmp-") for p in tmp_path.rglob("*")), list(
        tmp_path.rglob("*")
    )


def _ended(run: subprocess.Popen, tag: str, ranks: int, timeout: float) -> tuple[str, str]:
    """The run's (stdout, stderr) once mpiexec has ended; if it has not within `timeout`
    (a hang), every rank and mpiexec are killed (no rank left behind) and the test fails."""
    try:
        return run.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        for rank in range(ranks):
            pid = _rank_pid(int(tag), rank)
            if pid is not None:
                os.kill(pid, signal.SIGKILL)
        run.kill()
        run.communicate()
        pytest.fail(f"mpiexec still running {timeout:.0f} s on: a rank waits on one that ended")


def _run_to_end(n: int, argv: list[str], timeout: float) -> tuple[int, str]:
    """`mpiexec -n n ARGV` (two ranks in all), tagged for `_rank_pid`, run to its end: (exit
    status, stderr); a hang kills every rank and fails the test (`_ended`)."""
    tag = str(os.getpid())
    run = mpiexec(n, argv, popen=True, env={"MIXVI_KILL_TEST": tag})
    try:
        _, stderr = _ended(run, tag, 2, timeout)
    finally:
        if run.poll() is None:
            run.kill()
    return run.returncode, stderr


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_rank_interrupted_mid_solve_ends_the_run(tmp_path, signum):
    """SIGTERM / SIGINT to rank 1 while the ranks solve: rank 1 ends at once with 143 / 130
    (no collective exit handler: petsc4py's garbage clean-up duplicates a communicator, and
    rank 0 is inside the solve waiting for rank 1), mpiexec ends rank 0, whose clean-up
    leaves the previous run's files as they were, with no lock or staging folder. On the old
    code rank 1 waited in its exit handlers for rank 0 forever."""
    need_petsc()
    out, before = earlier_run(tmp_path)
    tag = str(os.getpid())
    run = mpiexec(
        2,
        [mixvi(), "solve", "paper_two_body", "--level", "4", "--cold", "--engine", "petsc"]
        + ["--out", str(out)],
        popen=True,
        env={"MIXVI_KILL_TEST": tag},
    )
    try:
        pid = _started_rank(tag, 1)
        while not (out / ".mixvi-lock").exists() and run.poll() is None:
            time.sleep(0.1)  # rank 0 has claimed the folder: the ranks build and solve
        assert run.poll() is None, run.communicate()
        time.sleep(1.0)
        os.kill(pid, signum)
        _, stderr = _ended(run, tag, 2, 90)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 128 + signum, stderr[-2000:]
    assert f"mixvi: interrupted by {signal.Signals(signum).name}" in stderr, stderr[-2000:]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.slow
def test_refused_on_one_rank_refused_on_every_rank(tmp_path):
    """A level that one rank's memory cannot hold (ulimit -v on rank 1 only) while rank 0's
    can: every rank refuses it with rank 1's line, exit status 2, no folder made. On the old
    code rank 0 went on into the solve and rank 1 waited for it in its exit handlers: a
    hang."""
    need_petsc()
    from problems.commands.resources import memory

    if memory()[1] < 5e9:
        pytest.skip("rank 0 must accept paper_two_body level 6 (up to 3.4 GB): too little memory")
    out = tmp_path / "o"
    argv = [mixvi(), "solve", "paper_two_body", "--level", "6", "--engine", "petsc"]
    argv += ["--out", str(out)]
    limited = ["bash", "-c", 'ulimit -v 3000000 && exec "$0" "$@"', *argv]  # 2.9 GiB
    status, stderr = _run_to_end(1, [*argv, ":", "-n", "1", *limited], 120)
    assert status == 2, stderr[-2000:]
    assert stderr.count("mixvi: error: --level = '6'") == 2, stderr  # each rank says why
    assert not out.exists()


@pytest.mark.slow
def test_rank_interrupted_while_rank_0_writes_ends_the_run(tmp_path):
    """SIGTERM to rank 1 once its solve is done, while rank 0 writes the results (rank 1
    waits for it in its collective exit handlers, where no Python handler runs): rank 1 ends
    at once, mpiexec ends rank 0, whose clean-up leaves the previous run as it was; exit
    status 143 and no traceback. On the old code the handler raised inside an exit handler
    once rank 0 was done ("Exception ignored in atexit callback", a traceback) and the run
    went on to exit 0."""
    need_petsc()
    out, before = earlier_run(tmp_path)
    tag = str(os.getpid())
    run = mpiexec(
        2,
        [mixvi(), "solve", "paper_two_body", "--level", "4", "--engine", "petsc"]
        + ["--out", str(out)],
        popen=True,
        env={"MIXVI_KILL_TEST": tag},
    )
    try:
        pid = _started_rank(tag, 1)

        def staged() -> bool:
            return any(p.name.startswith(".mixvi-tmp-") for p in out.iterdir())

        while not staged() and run.poll() is None:
            time.sleep(0.05)  # rank 0 writes into its staging folder: the solve is done
        assert run.poll() is None, run.communicate()
        os.kill(pid, signal.SIGTERM)
        _, stderr = _ended(run, tag, 2, 90)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 143, stderr[-2000:]
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr[-2000:]
    assert "signal 15" in stderr, stderr[-2000:]  # mpiexec names rank 1's end
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.slow
def test_output_refused_mid_load_path_ends_every_rank(tmp_path):
    """Rank 0 alone meets a refusal mid-solve: its file-size limit (ulimit -f 10 KiB) is
    reached writing a load step's files while rank 1 goes on to the next step. Rank 0 says
    why, cleans up (no folder left) and ends without the collective exit handlers, mpiexec
    ends rank 1: exit status 2. On the old code rank 0 waited in its exit handlers for rank 1,
    which waited for it in the next step's solve: a hang."""
    need_petsc()
    out = tmp_path / "o"
    # level 2: the first step's block.vtu (19 KB) is over the limit, rank 1 has 29 steps to go
    argv = [mixvi(), "solve", "shear_strip_path", "--level", "2", "--engine", "petsc"]
    argv += ["--out", str(out)]
    limited = ["bash", "-c", 'ulimit -f 10 && exec "$0" "$@"', *argv]
    status, stderr = _run_to_end(1, [*limited, ":", "-n", "1", *argv], 120)
    assert status == 2, stderr[-2000:]
    assert "mixvi: error: --out" in stderr and "ulimit -f" in stderr, stderr[-2000:]
    assert not out.exists()


def test_internal_error_on_one_rank_ends_the_run_with_the_serial_status(tmp_path):
    """A RuntimeError in rank 1's Newton loop alone (mpi_scene's "fail_rank_1"): rank 1 says
    so with the serial line and ends with the serial status of an internal error (3), mpiexec
    ends rank 0, whose clean-up leaves the previous run as it was. The old code called
    MPI_Abort(1): exit status 1, where the serial command exits 3."""
    need_petsc()
    import sys

    out, before = earlier_run(tmp_path)
    cli = [sys.executable, "-m", "tests.vi_core.petsc.mpi_cli", "--mutation", "fail_rank_1"]
    argv = [*cli, "solve", "paper_two_body", "--level", "2", "--engine", "petsc"]
    status, stderr = _run_to_end(2, [*argv, "--out", str(out)], 120)
    assert status == 3, stderr[-2000:]
    assert "mixvi: rank 1 of 2 failed (RuntimeError)" in stderr, stderr[-2000:]
    assert "mixvi: internal error: RuntimeError: injected on rank 1" in stderr, stderr[-2000:]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_serial_engine_under_mpiexec_refused_on_every_rank(tmp_path):
    """`mpiexec -n 2 mixvi solve` without --engine petsc: every rank refuses with one line
    naming --engine (exit 2, no folder). The old code ran two whole serial solves into one
    folder: one was refused by the other's lock, mpiexec then ended the other (exit 2, a
    message about a lock)."""
    need_petsc()
    out = tmp_path / "o"
    done = mpiexec(2, each_rank([mixvi(), "solve", SCENE, "--out", str(out)]), timeout=120)
    assert "rank 0: 2" in done.stderr and "rank 1: 2" in done.stderr, done.stderr[-2000:]
    assert done.stderr.count("mixvi: error: --engine = 'serial': petsc under mpiexec") == 2
    assert not out.exists()


def _upper(level: int) -> float:
    """SCENE's upper memory estimate at `level` (bytes): what each rank may need."""
    from problems import pipeline
    from problems.commands.resources import Sizes

    loaded = pipeline.load(SCENE)
    return Sizes(loaded.plugin, loaded.scene).estimate(level).upper_bytes


def _guarded_run(tmp_path: Path, available: float, *stand_ins: str) -> tuple[int, str, Path]:
    """`mpiexec -n 2 mixvi solve SCENE --level 0 --engine petsc` with the host's memory
    available now read as `available` bytes (mpi_cli's stand-in) and `stand_ins` (mpi_cli's
    other options): (exit status, stderr, the output folder)."""
    import sys

    out = tmp_path / "o"
    cli = [sys.executable, "-m", "tests.vi_core.petsc.mpi_cli", "--available", str(available)]
    argv = [*cli, *stand_ins, "solve", SCENE, "--level", "0", "--engine", "petsc"]
    status, stderr = _run_to_end(2, [*argv, "--out", str(out)], 120)
    return status, stderr, out


def test_ranks_on_one_host_are_refused_by_their_sum(tmp_path):
    """Two ranks on this host, which has 1.5 times what one rank may need: each fits alone,
    the two do not together. Every rank refuses with one line naming the sum, the ranks and
    what is available (exit 2), and no folder is made. On the old code each rank checked its
    own estimate only, and the run went on."""
    need_petsc()
    from problems.commands.resources import gb

    upper = _upper(0)
    status, stderr, out = _guarded_run(tmp_path, 1.5 * upper)
    assert status == 2, stderr[-2000:]
    says = f"2 ranks on this host need up to {gb(2 * upper)} together, {gb(1.5 * upper)} available"
    assert stderr.count(says) == 2, stderr[-2000:]
    assert stderr.count("mixvi: error: --level = '0'") == 2, stderr[-2000:]
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("factor", "stand_ins"),
    [(2.5, ()), (1.5, ("--host-per-rank",))],
    ids=["room_for_both", "a_host_each"],
)
def test_ranks_that_fit_their_host_solve(tmp_path, factor, stand_ins):
    """Two ranks that fit together (2.5 times one rank's upper estimate available), or that are
    on hosts of their own (each host 1.5 times: ranks on other hosts are not counted): the run
    solves and writes its results."""
    need_petsc()
    status, stderr, out = _guarded_run(tmp_path, factor * _upper(0), *stand_ins)
    assert status == 0, stderr[-2000:]
    assert (out / "summary.json").exists()


def test_mutation_counting_one_rank_per_host_is_seen(tmp_path):
    """The fault `test_ranks_on_one_host_are_refused_by_their_sum` catches: each rank counted
    alone on its host (mpi_scene's "host_one_rank"), the two ranks that do not fit together are
    let through and the run solves."""
    need_petsc()
    status, stderr, out = _guarded_run(tmp_path, 1.5 * _upper(0), "--mutation", "host_one_rank")
    assert status == 0, stderr[-2000:]
    assert "ranks on this host" not in stderr
