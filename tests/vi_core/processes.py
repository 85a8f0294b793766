"""Processes that share a row partition, for the tests of what vi_core computes from a
process's rows and reductions (`MixedVI.partition`, the petsc engine's slave rows): forked
processes, each with a stand-in of the engine's row partition
(`vi_core.petsc.runtime.RowPartition`: ``owned``, ``gatherv``, ``all_true``, ``norm``) whose
collectives exchange through queues. Processes, not threads: a collective inside a
cached_property (the scaling) would wait on Python 3.11's class-wide cached_property lock."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from vi_core import MixedVI

#: faults of a process's reductions the comparison must see: that process drops what the
#: others sent (its gatherv keeps its own part only, zeros elsewhere; its all_true and its norm
#: read its own value only)
FAULTS = ("gatherv", "all_true", "norm")


class World:
    """`size` forked processes exchanging values through queues; rows [cuts[r], cuts[r + 1])
    on process r."""

    def __init__(self, cuts: list[int]):
        self.cuts, self.size = cuts, len(cuts) - 1
        self.inbox = [CONTEXT.Queue() for _ in range(self.size)]
        self.calls = 0  # collectives so far (each process counts its own, after the fork)
        self.early: dict = {}  # (call, sender) → a value sent for a later collective

    def exchange(self, rank: int, value) -> list:
        """Every process's `value`, in rank order (a collective; queue.Empty if one of them
        stopped before it)."""
        call, self.calls = self.calls, self.calls + 1
        for r in range(self.size):
            if r != rank:
                self.inbox[r].put((call, rank, value))
        out = [None] * self.size
        out[rank] = value
        others = [r for r in range(self.size) if r != rank]
        while any((call, r) not in self.early for r in others):
            c, sender, got = self.inbox[rank].get(timeout=TIMEOUT)
            self.early[c, sender] = got
        for r in others:
            out[r] = self.early.pop((call, r))
        return out


CONTEXT = multiprocessing.get_context("fork")
TIMEOUT = 5.0  # s: a process waiting longer on a collective gives up (a peer stopped)


class Rows:
    """Process `rank`'s row partition (the protocol of `vi_core.engine.row_partition`); `fault`
    one of FAULTS: this process drops the others' parts in that reduction."""

    def __init__(self, world: World, rank: int, fault: str = ""):
        self.world, self.rank, self.fault = world, rank, fault

    def owned(self, n: int) -> tuple[int, int]:
        assert n == self.world.cuts[-1]
        return self.world.cuts[self.rank], self.world.cuts[self.rank + 1]

    def gatherv(self, local: np.ndarray) -> np.ndarray:
        parts = self.world.exchange(self.rank, np.asarray(local))
        if self.fault == "gatherv":
            parts = [p if r == self.rank else np.zeros_like(p) for r, p in enumerate(parts)]
        return np.concatenate(parts)

    def all_true(self, flag: bool) -> bool:
        flags = self.world.exchange(self.rank, bool(flag))
        return bool(flag) if self.fault == "all_true" else all(flags)

    def norm(self, local: np.ndarray) -> float:
        sums = self.world.exchange(self.rank, float(local @ local))
        return float(np.sqrt(sums[self.rank] if self.fault == "norm" else sum(sums)))


def on_processes(cuts: list[int], work: Callable[[Rows], object], faulty=-1, fault="") -> list:
    """work(rows) on each process (process `faulty` with `fault`): what each returned, or the
    repr of what it raised, in rank order."""
    world = World(cuts)
    results = CONTEXT.Queue()

    def run(r: int) -> None:
        try:
            results.put((r, work(Rows(world, r, fault if r == faulty else ""))))
        except Exception as err:  # noqa: BLE001  the test compares what each process raised
            results.put((r, repr(err)))

    procs = [CONTEXT.Process(target=run, args=(r,)) for r in range(world.size)]
    for p in procs:
        p.start()
    out: list = [None] * world.size
    for _ in procs:
        r, got = results.get(timeout=60)
        out[r] = got
    for p in procs:
        p.join()
    return out


def by_rows(vi: MixedVI, rows: Rows) -> MixedVI:
    """vi with A cut to the rows `rows` owns, under that partition."""
    lo, hi = rows.owned(vi.n)
    A = sp.csr_matrix(vi.A)[lo:hi]
    return MixedVI(
        A=A, B=vi.B, f=vi.f, Lambda=vi.Lambda, gap=vi.gap, fields=vi.fields, partition=rows
    )


def cuts_of(rng: np.random.Generator, n: int) -> list[int]:
    """2–4 contiguous row ranges of n rows, one possibly empty."""
    P = int(rng.integers(2, 5))
    inner = sorted(rng.integers(0, n + 1, size=P - 1).tolist())
    return [0, *inner, n]
