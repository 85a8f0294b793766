"""The petsc engine's layout of the Newton matrix (`vi_core.petsc.layout`): every group of
unknowns (a field's slave dofs, its other dofs) split evenly over the ranks, each rank's rows
increasing; the model's contiguous row blocks moved there (`Layout.moved`) are the rows and
columns of the whole matrix permuted, bit for bit. `moved` runs on forked processes with a
stand-in of mpi4py's all-to-all (tests/vi_core/processes.py); the mpi tier runs the engine on
MPI (test_every_scene.py, test_amg_quick.py)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core.petsc.layout import Layout, groups, node_groups, split

from ..processes import World, cuts_of, on_processes


def random_groups(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,) groups as the engine makes them: fields in runs (displacement, then potential),
    slave dofs scattered in the first field."""
    fields = {"displacement": np.arange(n) < int(rng.integers(1, n + 1))}
    if (~fields["displacement"]).any():
        fields["potential"] = ~fields["displacement"]
    first = np.flatnonzero(fields["displacement"])
    slaves = rng.choice(first, size=int(rng.integers(0, first.size + 1)), replace=False)
    return groups(n, fields, slaves)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_every_group_is_split_evenly_and_the_ranks_tile_the_unknowns(seed):
    rng = np.random.default_rng(seed)
    n, size = int(rng.integers(1, 60)), int(rng.integers(1, 6))
    g = random_groups(rng, n)
    layouts = [Layout.balanced(g, r, size) for r in range(size)]
    order = np.concatenate([lay.rows for lay in layouts])  # (n,) the PETSc order
    assert np.array_equal(np.sort(order), np.arange(n))  # each unknown on one rank
    for r, lay in enumerate(layouts):
        assert np.all(np.diff(lay.rows) > 0)
        assert lay.lo == lay.bounds[r] and lay.rows.size == lay.bounds[r + 1] - lay.lo
        assert np.array_equal(lay.new, layouts[0].new)
        assert np.array_equal(lay.new[lay.rows], lay.lo + np.arange(lay.rows.size))
    for label in np.unique(g):
        members = np.flatnonzero(g == label)  # (n_g,) in the unknowns' order
        held = np.concatenate([members[np.isin(members, lay.rows)] for lay in layouts])
        assert np.array_equal(held, members)  # contiguous chunks, in rank order
        counts = [np.isin(members, lay.rows).sum() for lay in layouts]
        assert np.array_equal(counts, np.diff(split(members.size, size)))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_groups_of_whole_nodes_are_split_between_nodes(seed):
    """A field whose unknowns come in nodes of c (`ksp.node_block`) with each node's unknowns
    all slave or none (`node_groups`: its two groups then have nodes of c): every rank holds
    whole nodes of each group, as evenly as nodes go (`split` of the nodes); a field with a
    node half slave keeps the split by unknowns."""
    rng = np.random.default_rng(seed)
    c, nodes, size = int(rng.integers(2, 4)), int(rng.integers(1, 20)), int(rng.integers(1, 5))
    n_p = int(rng.integers(0, 8))  # the potential's unknowns, one per node
    n = c * nodes + n_p
    fields = {"displacement": np.arange(n) < c * nodes}
    if n_p:
        fields["potential"] = ~fields["displacement"]
    slave_nodes = rng.random(nodes) < 0.4  # (nodes,)
    slaves = np.flatnonzero(np.repeat(slave_nodes, c))
    g = groups(n, fields, slaves)
    nodes_of = node_groups(g, fields, {"displacement": c})
    assert nodes_of == {0: c, 1: c}
    for label in (0, 1):
        members = np.flatnonzero(g == label)  # (n_g,) whole nodes, in order
        counts = [np.isin(members, Layout.balanced(g, r, size, nodes=nodes_of).rows).sum()
                  for r in range(size)]  # fmt: skip
        assert np.array_equal(counts, c * np.diff(split(members.size // c, size)))
    if slaves.size:  # a node made part slave (its first unknown not)
        assert node_groups(groups(n, fields, slaves[1:]), fields, {"displacement": c}) == {}
    assert node_groups(g, fields, {"displacement": 1}) == {}


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_fields_rows_and_near_null_rows_are_its_unknowns_here(seed):
    """field_rows: the PETSc rows of the field's unknowns on this rank; field_positions: where
    they stand in the field's own order (the rows of its near-null vectors)."""
    rng = np.random.default_rng(seed)
    n, size = int(rng.integers(2, 60)), int(rng.integers(1, 5))
    mask = rng.random(n) < 0.6
    N = rng.standard_normal((int(mask.sum()), 3))  # (n_f, 3) vectors in the field's order
    whole = np.zeros((n, 3))
    whole[mask] = N  # (n, 3) by unknown
    g = random_groups(rng, n)
    for r in range(size):
        lay = Layout.balanced(g, r, size)
        rows = lay.field_rows(mask)
        assert np.array_equal(rows, lay.new[lay.rows[mask[lay.rows]]])
        assert np.array_equal(N[lay.field_positions(mask)], whole[lay.rows[mask[lay.rows]]])


class AllToAll:
    """mpi4py's alltoall and Alltoallv (buffer form) over a `processes.World`."""

    def __init__(self, world: World, rank: int):
        self.world, self.rank = world, rank

    def alltoall(self, values: list) -> list:
        return [v[self.rank] for v in self.world.exchange(self.rank, values)]

    def allgather(self, value) -> list:
        return self.world.exchange(self.rank, value)

    def Alltoallv(self, send: list, recv: list) -> None:  # noqa: N802  mpi4py's name
        local, (counts, offsets) = send
        chunks = [local[o : o + c] for c, o in zip(counts, offsets, strict=True)]
        got = [parts[self.rank] for parts in self.world.exchange(self.rank, chunks)]
        out, (counts_in, _) = recv
        assert [len(x) for x in got] == list(counts_in)
        out[:] = np.concatenate(got)


def moved_everywhere(seed: int, fault: str = "") -> list:
    """Whether each process's `moved` rows of a random sparse matrix, held by random
    contiguous row blocks, are the whole matrix's rows and columns in the layout (values,
    columns, row pointers); fault "zeroed": the last row of the first process with rows
    reaches its rank zeroed."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 40))
    M = sp.random(n, n, density=0.3, format="csr", random_state=rng) + sp.eye(n)
    M = sp.csr_matrix(M)
    M.sort_indices()
    cuts = cuts_of(rng, n)
    size = len(cuts) - 1
    g = random_groups(rng, n)
    order = np.concatenate([Layout.balanced(g, r, size).rows for r in range(size)])
    P = sp.csr_matrix(M[order][:, order])  # the whole matrix in the layout
    P.sort_indices()
    faulty = next(r for r in range(size) if cuts[r + 1] > cuts[r])  # the first with rows

    def work(rows) -> bool:
        lay = Layout.balanced(g, rows.rank, size)
        lo, hi = rows.owned(n)
        block = sp.csr_matrix(M[lo:hi][lay.sending(lo, hi)])
        if fault == "zeroed" and rows.rank == faulty:
            block.data[block.indptr[-2] :] = 0.0  # the last row's values lost on the way
        got = lay.moved(block, lo, hi, AllToAll(rows.world, rows.rank))
        want = P[lay.lo : lay.lo + lay.rows.size]
        return all(
            np.array_equal(a, b)
            for a, b in (
                (got.data, want.data),
                (got.indices, want.indices),
                (got.indptr, want.indptr),
            )
        )

    return on_processes(cuts, work, 0, "")


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_moved_rows_are_the_whole_matrix_in_the_layout(seed):
    assert all(g is True for g in moved_everywhere(seed))


@pytest.mark.parametrize("fault", ["zeroed"])
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_a_row_lost_on_the_way_is_seen(fault, seed):
    """Mutation: a process's last row reaches its rank with its values lost."""
    assert not all(g is True for g in moved_everywhere(seed, fault))


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_off_rank_counts_the_couplings_across_ranks(seed):
    """`off_rank` over the ranks' row blocks (chunked: CHUNK lowered to 3 rows) is the count
    of the whole matrix's entries whose row and column the layout puts on different ranks."""
    from vi_core.petsc import layout

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 50))
    M = sp.csr_matrix(sp.random(n, n, density=0.2, format="csr", random_state=rng))
    cuts = cuts_of(rng, n)
    size = len(cuts) - 1
    lay = Layout.balanced(random_groups(rng, n), 0, size)
    holder = np.searchsorted(lay.bounds, lay.new, side="right") - 1  # (n,)
    rows, cols = M.nonzero()
    want = int(np.count_nonzero(holder[rows] != holder[cols]))
    chunk, layout.CHUNK = layout.CHUNK, 3
    try:
        got = sum(lay.off_rank(M[lo:hi], lo) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True))
    finally:
        layout.CHUNK = chunk
    assert got == want
