"""`mixvi study` on Dask: the same numbers as the serial study (all but times and memory
peaks), a failed task as a failed row with its cause, refusals for bad --workers values.

Needs the optional extra (`pip install mixvi[dask]`); skipped without it."""

from __future__ import annotations

import copy

import pytest

from problems.commands import study
from problems.commands.main import main
from problems.plugins import registry
from problems.scene import load_scene

distributed = pytest.importorskip("dask.distributed")

MEASURED = ("time_s", "peak_mem_mb")  # the only entries allowed to differ between runs


def numbers(result: dict) -> dict:
    """The study result without what is measured rather than computed."""
    out = copy.deepcopy(result)
    for r in out["records"]:
        for k in MEASURED:
            r.pop(k, None)
    return out


@pytest.fixture(scope="module")
def cluster_client():
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


@pytest.mark.parametrize(
    "name, solvers",
    [("obstacle", ["ssn", "conic"]), ("signorini", ["ssn"])],  # exact / reference errors
)
def test_dask_study_gives_the_serial_numbers(cluster_client, name, solvers):
    scene = load_scene(name)
    args = (scene, [0, 1], solvers, [1e-6, 1e-9], False)
    serial = study.run_study(*args)
    spread = study.run_study(*args, client=cluster_client)
    assert numbers(spread) == numbers(serial)
    assert all(r["converged"] for r in spread["records"])


def test_the_comparison_catches_one_changed_number():
    """Mutation: the comparison above sees a residual changed in its last bit."""
    result = {"records": [{"residual": 1e-12, "time_s": 1.0, "err": {"h1": 0.1}}]}
    other = copy.deepcopy(result)
    other["records"][0]["time_s"] = 2.0
    assert numbers(other) == numbers(result)
    other["records"][0]["residual"] = 1e-12 * (1 + 2**-52)
    assert numbers(other) != numbers(result)


def test_a_failed_task_is_a_failed_row_with_its_cause(monkeypatch):
    scene = load_scene("obstacle")
    plugin = registry.for_scene(scene)
    real = plugin.build

    def build(scene, level=None):
        if level == 1:
            raise RuntimeError("the mesh generator crashed")
        return real(scene, level)

    monkeypatch.setattr(plugin, "build", build)
    with (
        distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as cl,
        distributed.Client(cl) as client,
    ):
        result = study.run_study(scene, [0, 1], ["ssn"], [1e-8], False, client=client)
    good, bad = result["records"]
    assert good["level"] == 0 and good["converged"] and good["err"]["h1"] > 0
    assert bad["level"] == 1 and not bad["converged"] and bad["err"] is None
    assert bad["error"] == "RuntimeError: the mesh generator crashed"
    assert "failed: RuntimeError: the mesh generator crashed" in study.table(result)


@pytest.mark.parametrize("value", ["0", "-2", "two", "1e3"])
def test_bad_worker_counts_are_refused(value, tmp_path, capsys):
    assert main(["study", "obstacle", "--workers", value, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--workers" in err and value in err and "1 … 256" in err
    assert not (tmp_path / "o").exists()


class Started(Exception):
    """Raised by the stand-in cluster once it knows how many workers it was asked for."""


def asked_workers(monkeypatch, argv: list[str]) -> list[int]:
    """`mixvi study argv` up to the start of its local cluster (a stand-in that records
    n_workers and stops the run): the worker counts asked for."""
    asked = []

    def cluster(n_workers, **kwargs):
        asked.append(n_workers)
        raise Started

    monkeypatch.setattr(distributed, "LocalCluster", cluster)
    with pytest.raises(Started):
        study.study_main(argv)
    return asked


def test_256_workers_on_this_machine_are_lowered_to_its_cores_with_a_notice(
    tmp_path, capsys, monkeypatch
):
    """issue 29: `--workers 256` on a 2-core machine was killed for memory."""
    argv = ["paper_two_body", "--levels", "0..3", "--solvers", "ssn,conic,homotopy"]
    asked = asked_workers(monkeypatch, [*argv, "--workers", "256", "--out", str(tmp_path / "o")])
    assert asked == [min(study.cores(), 12)]  # 4 levels × 3 solvers = 12 cases
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mixvi study: --workers 256 lowered to {asked[0]}")
    assert f"{study.cores()} cores" in err[0] and "per worker" in err[0]


def test_workers_are_lowered_to_those_whose_memory_fits(tmp_path, capsys, monkeypatch):
    """With 1 GB available and ~0.4 GB per worker at level 4: 2 workers of the 4 asked (for 3
    cases on 64 cores)."""
    monkeypatch.setattr(study, "cores", lambda: 64)
    monkeypatch.setattr(study.resources, "memory", lambda: (64e9, 1e9))
    argv = ["paper_two_body", "--levels", "4..4", "--solvers", "ssn,conic,homotopy"]
    asked = asked_workers(monkeypatch, [*argv, "--workers", "4", "--out", str(tmp_path / "o")])
    scene = load_scene("paper_two_body")
    per = study.resources.Sizes(registry.for_scene(scene), scene).estimate(4).upper_bytes
    assert asked == [int(1e9 // (per + study.DASK_WORKER_BYTES))] == [2]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"lowered to {asked[0]}" in err[0] and "1.0 GB available" in err[0]


def test_workers_that_fit_are_started_as_asked(tmp_path, capsys, monkeypatch):
    argv = ["obstacle", "--levels", "0..1", "--solvers", "ssn", "--workers", "1"]
    assert asked_workers(monkeypatch, [*argv, "--out", str(tmp_path / "o")]) == [1]
    assert capsys.readouterr().err == ""
