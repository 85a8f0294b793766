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

from vi_core.petsc.layout import Layout, chosen, groups, split

from ..processes import World, cuts_of, on_processes


def random_labels(rng: np.random.Generator, n: int) -> tuple:
    """(fields, blocks (n,) or None, slaves) as the engine has them: fields in runs
    (displacement, then potential), 1–3 blocks (bodies) of random labels in runs, slave dofs
    scattered in the first field."""
    fields = {"displacement": np.arange(n) < int(rng.integers(1, n + 1))}
    if (~fields["displacement"]).any():
        fields["potential"] = ~fields["displacement"]
    cuts = np.sort(rng.integers(0, n + 1, size=int(rng.integers(0, 3))))
    labels = rng.choice(100, size=cuts.size + 1, replace=False)  # not 0, 1, …: any labels
    blocks = None if rng.random() < 0.2 else labels[np.searchsorted(cuts, np.arange(n), "right")]
    first = np.flatnonzero(fields["displacement"])
    slaves = rng.choice(first, size=int(rng.integers(0, first.size + 1)), replace=False)
    return fields, blocks, slaves


def random_groups(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,) groups as the engine makes them (`random_labels`)."""
    return groups(n, *random_labels(rng, n))


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
def test_each_blocks_field_is_split_evenly(seed):
    """Every (block, field, slave or not) of the labels, read from them and not from `groups`,
    is split over the ranks as PETSc splits a range (mutation: the blocks ignored in `groups`
    splits the union of the blocks' fields, not each block's)."""
    rng = np.random.default_rng(seed)
    n, size = int(rng.integers(1, 60)), int(rng.integers(2, 5))
    fields, blocks, slaves = random_labels(rng, n)
    layouts = [Layout.balanced(groups(n, fields, blocks, slaves), r, size) for r in range(size)]
    slave = np.isin(np.arange(n), slaves)
    for b in np.unique(blocks if blocks is not None else [0]):
        inside = np.ones(n, bool) if blocks is None else blocks == b
        for mask in fields.values():
            for s in (False, True):
                members = np.flatnonzero(inside & mask & (slave == s))  # (n_g,)
                counts = [np.isin(members, lay.rows).sum() for lay in layouts]
                assert np.array_equal(counts, np.diff(split(members.size, size)))


def two_bodies(nodes: tuple[int, int]) -> tuple[sp.csr_matrix, dict, np.ndarray]:
    """A paper_two_body in small: two chains of nodes, body 0 displacement only (2 dofs a
    node), body 1 displacement and potential (3 a node), numbered body by body as the contact
    model does (body 0's displacement, body 1's, body 1's potential), each dof coupled to every
    dof of its node and the neighbouring nodes of its body; (A (n, n), fields, blocks (n,))."""
    rows, cols, disp, blocks, start = [], [], [], [], 0
    for body, (count, per) in enumerate(zip(nodes, (2, 3), strict=True)):
        d = 2 * count  # the body's displacement dofs, node-major, then its potential's
        dof = np.array(
            [
                [start + 2 * k, start + 2 * k + 1] + [start + d + k] * (per == 3)
                for k in range(count)
            ]
        )  # (count, per) the dofs of each node
        for k in range(count):
            near = dof[max(k - 1, 0) : k + 2].ravel()
            rows += np.repeat(dof[k], near.size).tolist()
            cols += np.tile(near, per).tolist()
        disp += [True] * d + [False] * (count * per - d)
        blocks += [body] * (count * per)
        start += count * per
    A = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(start, start))
    disp = np.array(disp)
    return A, {"displacement": disp, "potential": ~disp}, np.array(blocks)


class Whole:
    """mpi4py's communicator for `chosen` on rank 0 of 2 given the whole matrix: its off-rank
    count is the sum over the ranks already."""

    def Get_rank(self) -> int:  # noqa: N802  mpi4py's name
        return 0

    def Get_size(self) -> int:  # noqa: N802
        return 2

    def allreduce(self, value: int) -> int:
        return value


@pytest.mark.parametrize("nodes", [(30, 40), (20, 50)])
def test_the_bodies_keep_a_nodes_displacement_and_potential_together(nodes):
    """Two bodies (`two_bodies`, even node counts): split by field alone, the second body's
    displacement and potential of one node land on different ranks, and the even split puts
    its potential on rank 1 alone; split by body and field, each body's chain is cut once, between
    two nodes (2 × 2 + 3 × 3 entries each way), and `chosen` takes that layout (mutation: the
    blocks ignored)."""
    A, fields, blocks = two_bodies(nodes)
    n, none = A.shape[0], np.zeros(0, dtype=np.int64)
    off = {
        name: Layout.balanced(g, 0, 2).off_rank(A, 0)
        for name, g in [
            ("even", np.zeros(n, dtype=np.int64)),
            ("fields", groups(n, fields, None, none)),
            ("bodies", groups(n, fields, blocks, none)),
        ]
    }
    assert min(off["fields"], off["even"]) > off["bodies"] == 2 * (2 * 2 + 3 * 3)
    lay = chosen(n, fields, blocks, none, A, 0, Whole())
    assert lay.kind == "fields" and lay.off_rank(A, 0) == off["bodies"]


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
