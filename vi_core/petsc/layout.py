"""The PETSc layout of the condensed Newton matrix: which unknowns each rank's rows of the
`mpiaij` matrix hold, balanced over the fields.

The unknowns are numbered field by field (all displacement dofs, then the potential's) and the
slave dofs of the condensation are the contact surface's, so PETSc's even split of 0..n−1 gave
one rank displacement rows only, every slave row among them, and the other the potential: the
displacement block's multigrid (d components, its rigid-body modes) costs more per row, and
that rank's peak was the run's (block3d level 2 on 2 ranks: 44 / 39 MiB above the imports).
Here every group of unknowns (a field's slave dofs, its other dofs) is split evenly over the
ranks in its own order, contiguous chunks as PETSc splits a range (`split`); a rank's rows are
its chunks of every group, in the unknowns' order. The layout is computed alike on every rank
from replicated data (the fields, the slave dofs): no communication.

The model's own row partition (`runtime.RowPartition`, contiguous [lo, hi): what each rank
assembles of A) is not changed; the Newton matrix's fixed rows are assembled there and moved to
this layout once (`Layout.moved`, one all-to-all; no second copy of the matrix is kept).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp


def split(count: int, size: int) -> np.ndarray:
    """(size + 1,) the bounds of `count` items split into `size` contiguous chunks as PETSc
    splits a range (PetscSplitOwnership: the first count mod size chunks one larger)."""
    base, extra = divmod(count, size)
    sizes = np.full(size, base, dtype=np.int64)
    sizes[:extra] += 1
    return np.concatenate([[0], np.cumsum(sizes)])


CHUNK = 4096  # rows per chunk of `Layout.off_rank`


@dataclass(frozen=True)
class Layout:
    """The PETSc layout of n unknowns over `size` ranks, seen from `rank`.

    rows : (k,) the unknowns (original indices, increasing) this rank's PETSc rows hold; PETSc
        row lo + j is unknown rows[j].
    lo : this rank's first PETSc row (the rows of the ranks before it).
    new : (n,) the PETSc row of each unknown.
    bounds : (size + 1,) the ranks' first PETSc rows, then n.
    kind : "even" (one group: PETSc's even split of 0..n−1) or "fields" (`chosen`)."""

    rows: np.ndarray
    lo: int
    new: np.ndarray
    bounds: np.ndarray
    kind: str = "fields"

    @classmethod
    def balanced(
        cls,
        groups: np.ndarray,
        rank: int,
        size: int,
        kind: str = "fields",
        nodes: dict[int, int] | None = None,
    ) -> Layout:
        """Each group of unknowns (groups (n,) int: the group of each unknown) split evenly
        over the ranks in the unknowns' order (`split`); rank r holds chunk r of every group.
        nodes: group → its unknowns per node, for groups whose members come in whole nodes
        (that many consecutive members each): their nodes are split evenly, no node cut."""
        owner = np.empty(groups.size, dtype=np.int64)  # (n,) the rank holding each unknown
        for g in np.unique(groups):
            members = np.flatnonzero(groups == g)  # (n_g,) increasing
            c = (nodes or {}).get(int(g), 1)
            bounds = c * split(members.size // c, size)  # (size + 1,)
            owner[members] = np.repeat(np.arange(size), np.diff(bounds))
        order = np.argsort(owner, kind="stable")  # (n,) by rank, each rank's in increasing order
        new = np.empty(groups.size, dtype=np.int64)
        new[order] = np.arange(groups.size)
        bounds = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=size))])
        lo = int(bounds[rank])
        return cls(order[lo : bounds[rank + 1]], lo, new, bounds, kind)

    def off_rank(self, block: sp.csr_matrix, lo: int) -> int:
        """The entries of `block` ((k_p, n) csr: the rows of the unknowns lo, lo + 1, …,
        columns by unknown) whose row and column this layout puts on different ranks (the
        couplings a rank's rows reach off it; counted by chunks of rows: no temporary of the
        block's size)."""
        holder = self._holder(0, self.new.size)  # (n,)
        count, ip = 0, block.indptr
        for start in range(0, block.shape[0], CHUNK):
            stop = min(start + CHUNK, block.shape[0])
            cols = holder[block.indices[ip[start] : ip[stop]]]  # (nnz_c,)
            rows = np.repeat(holder[lo + start : lo + stop], np.diff(ip[start : stop + 1]))
            count += int(np.count_nonzero(cols != rows))
        return count

    def _holder(self, lo: int, hi: int) -> np.ndarray:
        """(hi − lo,) the rank whose layout rows hold each of the unknowns lo, …, hi − 1."""
        return np.searchsorted(self.bounds, self.new[lo:hi], side="right") - 1

    def sending(self, lo: int, hi: int) -> np.ndarray:
        """(hi − lo,) the unknowns lo, …, hi − 1 (as offsets from lo) in the order `moved`
        sends them: by the rank holding them, increasing within each rank."""
        return np.argsort(self._holder(lo, hi), kind="stable")

    def moved(self, block: sp.csr_matrix, lo: int, hi: int, comm: Any) -> sp.csr_matrix:
        """(k, n) this rank's rows of the layout, columns as PETSc rows (`new`), sorted, from
        the ranks' `block`s ((hi − lo, n) csr, columns by unknown: the rows of the unknowns
        lo, …, hi − 1 in `sending` order; the ranks' [lo, hi) contiguous and in rank order, as
        the model's row partition): each row sent to the rank holding it (MPI_Alltoallv,
        mpi4py's `comm`). A rank receives its rows from the ranks in order, each's increasing:
        the layout's order (its rows increasing). `block` is consumed (its columns rewritten)."""
        size = self.bounds.size - 1
        dest = np.sort(self._holder(lo, hi))  # (hi − lo,) of block's rows
        lengths = np.diff(block.indptr)  # (hi − lo,)
        rows_to = np.bincount(dest, minlength=size)  # (size,)
        nnz_to = np.bincount(dest, weights=lengths, minlength=size).astype(np.int64)
        rows_from = np.asarray(comm.alltoall(rows_to.tolist()))  # (size,)
        arrive = comm.allgather(int(rows_from.sum()) == self.rows.size)  # (size,) on every rank
        if not all(arrive):  # every rank refuses alike (no rank left waiting in the exchange)
            bad = [r for r, ok in enumerate(arrive) if not ok]
            raise ValueError(f"the layout's rows do not arrive where it puts them (ranks {bad})")
        nnz_from = np.asarray(comm.alltoall(nnz_to.tolist()))  # (size,)
        block.indices = self.new[block.indices].astype(block.indices.dtype)  # PETSc columns
        lengths = _exchange(comm, lengths, rows_to, rows_from)  # (k,)
        indices = _exchange(comm, block.indices, nnz_to, nnz_from)  # (nnz,)
        data = _exchange(comm, block.data, nnz_to, nnz_from)  # (nnz,)
        indptr = np.zeros(lengths.size + 1, dtype=indices.dtype)
        np.cumsum(lengths, out=indptr[1:])
        out = sp.csr_matrix((data, indices, indptr), shape=(lengths.size, block.shape[1]))
        out.sort_indices()
        return out

    def field_rows(self, mask: np.ndarray) -> np.ndarray:
        """(k_f,) the PETSc rows on this rank of the unknowns of mask ((n,) bool)."""
        return self.lo + np.flatnonzero(mask[self.rows])

    def field_positions(self, mask: np.ndarray) -> np.ndarray:
        """(k_f,) the positions, in the field's own order (mask's unknowns increasing), of the
        field's unknowns on this rank's rows: the rows of the field's near-null vectors."""
        return (np.cumsum(mask) - 1)[self.rows[mask[self.rows]]]


def _exchange(comm: Any, local: np.ndarray, to: np.ndarray, frm: np.ndarray) -> np.ndarray:
    """The entries the ranks send this one (MPI_Alltoallv): local[chunk r] goes to rank r
    (to (size,) the chunks' lengths, frm (size,) what each rank sends here), received in rank
    order."""
    local = np.ascontiguousarray(local)
    out = np.empty(int(frm.sum()), dtype=local.dtype)
    comm.Alltoallv([local, (to, _offsets(to))], [out, (frm, _offsets(frm))])
    return out


def _offsets(counts: np.ndarray) -> np.ndarray:
    """(size,) where each chunk of `counts` (size,) starts."""
    return np.concatenate([[0], np.cumsum(counts)[:-1]])


def chosen(
    n: int,
    fields: dict | None,
    slaves: np.ndarray,
    block: sp.csr_matrix,
    lo: int,
    comm: Any,
    per_node: dict[str, int] | None = None,
) -> Layout:
    """The layout of the linear solve: the fields balanced (`groups`) unless that puts more
    of the matrix's couplings across ranks than PETSc's even split of 0..n−1 (one group);
    block (k_p, n): this rank's rows lo, lo + 1, … of the matrix's structure (the model's
    rows of A), its off-rank entries summed over the ranks (mpi4py's `comm`). Where the
    fields' runs follow one mesh in one node order (block3d: displacement, then potential,
    of one body) the balanced layout keeps each node's unknowns together and cuts the
    couplings across ranks (block3d level 2 on 2 ranks: 129968 → 60911 entries each way);
    where they do not (paper_two_body: the displacements of two bodies, then the potential of
    one) it splits a body's displacement from its potential (67754 → 165767) and the even
    split is kept. per_node: field → its unknowns per node where the field's unknowns come in
    whole nodes (`ksp.node_block`): the balanced layout then cuts no node of its groups
    (`node_groups`), so each rank's rows of the field are whole nodes (GAMG's block size)."""
    rank, size = comm.Get_rank(), comm.Get_size()
    g = groups(n, fields, slaves)
    candidates = [
        Layout.balanced(np.zeros(n, dtype=np.int64), rank, size, "even"),
        Layout.balanced(g, rank, size, nodes=node_groups(g, fields, per_node or {})),
    ]
    off = [comm.allreduce(c.off_rank(block, lo)) for c in candidates]
    return candidates[int(np.argmin(off))]  # the even split on a tie (one rank)


def groups(n: int, fields: dict | None, slaves: np.ndarray) -> np.ndarray:
    """(n,) the group of each unknown `Layout.balanced` splits: 2 · (its field's index in
    `fields`, 0 without fields) + (1 on the condensation's slave dofs `slaves`)."""
    out = np.zeros(n, dtype=np.int64)
    for i, mask in enumerate((fields or {}).values()):
        out[mask] = 2 * i
    out[slaves] += 1
    return out


def node_groups(g: np.ndarray, fields: dict | None, per_node: dict[str, int]) -> dict[int, int]:
    """group → unknowns per node (`Layout.balanced`'s nodes) for the groups of `g` ((n,),
    `groups`) of each field of per_node (c > 1: the field's unknowns, in order, are whole nodes
    of c) whose every node lies in one group (a node's c unknowns all slave, or none)."""
    out = {}
    for i, (name, mask) in enumerate((fields or {}).items()):
        c = per_node.get(name, 1)
        if c < 2:
            continue
        labels = g[mask].reshape(-1, c)  # (nodes, c) the group of each unknown of each node
        if (labels == labels[:, :1]).all():
            out |= {2 * i: c, 2 * i + 1: c}
    return out
