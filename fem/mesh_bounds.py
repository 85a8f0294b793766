"""Bounds on a mesh file, checked before meshio allocates anything from it.

meshio trusts a file's counts and tags: a gmsh node tag of 10⁹ makes it allocate an array as
long as the tag (4–8 GB), a count in a header one as long as the count; a duplicate node tag
silently overwrites a node, and a cell naming a tag no node has gets node −1 (the last node).
A FIFO blocks it forever, a symbolic link to /dev/zero fills the memory. So, before meshio
reads a file (`check_file`, `scan_gmsh_ascii`, `address_space_cap`):

- only a regular file of at most MAX_FILE_BYTES (after following symbolic links);
- gmsh ASCII (.msh v2 and v4): every count at most what the file's size can hold, node tags
  positive, unique and at most MAX_TAG_FACTOR × (number of nodes) + MAX_TAG_SLACK (meshio's
  lookup array is as long as the largest tag), and every node a cell names present;
- any format: while meshio reads, the process's address space is capped at what it has now
  plus READ_BYTES_PER_FILE_BYTE × the file's size + READ_BASE_BYTES (RLIMIT_AS, restored
  afterwards), so a count or tag that slips through fails with MemoryError at once instead of
  taking the machine's memory.

Each refusal is a `MeshImportError` naming the file, the section or line and what is allowed.
"""

from __future__ import annotations

import contextlib
import os
import resource
import stat
from collections.abc import Iterator

import numpy as np

MAX_FILE_BYTES = 2 * 2**30  # a mesh file larger than this is refused (about 20M nodes)
MAX_TAG_FACTOR = 8  # node tags at most MAX_TAG_FACTOR × n_nodes + MAX_TAG_SLACK
MAX_TAG_SLACK = 2**20
MIN_NODE_LINE = 6  # the shortest node line "t x y\n" of a gmsh ASCII file, in bytes
MIN_CELL_LINE = 6  # the shortest cell line "t k n\n", in bytes
# address space allowed for meshio's read beyond what the process holds: a v4.1 file of N
# nodes is about 60 N bytes and meshio holds about 100 N bytes of arrays for it
READ_BYTES_PER_FILE_BYTE = 32
READ_BASE_BYTES = 512 * 2**20


def check_file(path: str, error) -> int:
    """The size of `path` if it is a regular file of at most MAX_FILE_BYTES; else
    `error(what, allowed)` (an exception to raise) for a FIFO, a device, a folder, a file too
    large or missing."""
    try:
        st = os.stat(path)
    except OSError as err:
        raise error("cannot be read", f"an existing, readable file ({err.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        kinds = {stat.S_IFIFO: "a named pipe (FIFO)", stat.S_IFCHR: "a device"}
        kinds |= {stat.S_IFBLK: "a device", stat.S_IFDIR: "a folder"}
        kind = kinds.get(stat.S_IFMT(st.st_mode), "not a regular file")
        raise error(kind, "a regular mesh file (not a pipe, device or folder)")
    if st.st_size > MAX_FILE_BYTES:
        raise error(f"{st.st_size:,} bytes", f"a mesh file of at most {MAX_FILE_BYTES:,} bytes")
    return st.st_size


def _lines(path: str) -> Iterator[tuple[int, str]]:
    with open(path, "rb") as fh:
        for i, raw in enumerate(fh, start=1):
            yield i, raw.decode("latin-1").strip()


class _Scan:
    """The node tags and the node tags cells name, gathered from a gmsh ASCII file."""

    def __init__(self, path: str, size: int, error):
        self.path, self.size, self.error = path, size, error
        self.tags: list[int] = []
        self.refs: list[int] = []
        self.first_ref: dict[int, int] = {}  # node tag → the line of a cell that names it

    def count(self, text: str, line: int, what: str, min_bytes: int) -> int:
        """A count read from a header, bounded by what the file's size can hold."""
        n = _int(text, line, what, self.error)
        most = self.size // min_bytes
        if not 0 <= n <= most:
            raise self.error(
                f"line {line}: {what} {n}",
                f"a count from 0 to {most:,} (what a file of {self.size:,} bytes can hold)",
            )
        return n

    def node(self, lines: Iterator[tuple[int, str]]) -> None:
        """Read a node line ("tag ..."): its tag."""
        i, tok = _next(lines, self, "$Nodes")
        self.tags.append(_int(tok[0], i, "node tag", self.error))

    def cell(self, i: int, refs: list[str]) -> None:
        """The node tags `refs` that the cell of line i names."""
        for t in refs:
            ref = _int(t, i, "node tag", self.error)
            self.refs.append(ref)
            self.first_ref.setdefault(ref, i)

    def check(self) -> None:
        """Tags positive, unique, bounded; every tag a cell names present."""
        if not self.tags:
            return
        tags = np.asarray(self.tags, dtype=np.int64)  # (n_nodes,)
        bound = MAX_TAG_FACTOR * tags.size + MAX_TAG_SLACK
        bad = np.flatnonzero((tags < 1) | (tags > bound))
        if bad.size:
            raise self.error(
                f"node tag {int(tags[bad[0]])}",
                f"node tags from 1 to {bound:,} ({MAX_TAG_FACTOR} × the {tags.size:,} nodes "
                f"+ {MAX_TAG_SLACK:,}: meshio allocates an array as long as the largest tag); "
                "renumber the nodes (gmsh: Mesh.Renumber)",
            )
        uniq, counts = np.unique(tags, return_counts=True)
        if (counts > 1).any():
            t = int(uniq[np.argmax(counts > 1)])
            raise self.error(
                f"node tag {t} given {int(counts.max())} times",
                "one node per tag (a mesh file gmsh wrote; merged files need renumbering)",
            )
        refs = np.asarray(self.refs, dtype=np.int64)  # (n_refs,)
        missing = refs[~np.isin(refs, uniq)]
        if missing.size:
            t = int(missing[0])
            raise self.error(
                f"line {self.first_ref.get(t, '?')}: a cell names node tag {t}, which no node "
                f"has ({np.unique(missing).size} such tag(s))",
                "cells whose nodes are all in the file's $Nodes section",
            )


def _int(text: str, line: int, what: str, error) -> int:
    try:
        return int(text)
    except ValueError:
        raise error(f"line {line}: {what} {text[:40]!r}", "an integer") from None


def scan_gmsh_ascii(path: str, size: int, error) -> None:
    """Check the counts and tags of a gmsh ASCII file (v2 or v4) before meshio reads it
    (module docstring); binary and other files are left to `address_space_cap`. Refusals:
    `error(what, allowed)`."""
    with open(path, "rb") as fh:
        head = fh.read(64).decode("latin-1").split()
    if len(head) < 3 or head[0] != "$MeshFormat" or head[2] != "0":
        return  # not gmsh, or binary
    version = head[1]
    scan = _Scan(path, size, error)
    lines = _lines(path)
    for _, text in lines:
        if text == "$Nodes":
            (_nodes_v2 if version.startswith("2") else _nodes_v4)(scan, lines, version)
        elif text == "$Elements":
            (_cells_v2 if version.startswith("2") else _cells_v4)(scan, lines, version)
    scan.check()


def _next(lines: Iterator[tuple[int, str]], scan: _Scan, what: str) -> tuple[int, list[str]]:
    for i, text in lines:
        if text:
            return i, text.split()
    raise scan.error(f"the file ends inside {what}", "a complete gmsh file")


def _nodes_v2(scan: _Scan, lines, version: str) -> None:
    i, tok = _next(lines, scan, "$Nodes")
    n = scan.count(tok[0], i, "number of nodes", MIN_NODE_LINE)
    for _ in range(n):
        scan.node(lines)


def _cells_v2(scan: _Scan, lines, version: str) -> None:
    i, tok = _next(lines, scan, "$Elements")
    n = scan.count(tok[0], i, "number of elements", MIN_CELL_LINE)
    for _ in range(n):
        i, tok = _next(lines, scan, "$Elements")
        k = _int(tok[2], i, "number of tags", scan.error) if len(tok) > 2 else len(tok)
        scan.cell(i, tok[3 + k :])


def _nodes_v4(scan: _Scan, lines, version: str) -> None:
    i, tok = _next(lines, scan, "$Nodes")
    blocks = scan.count(tok[0], i, "number of entity blocks", MIN_NODE_LINE)
    total = scan.count(tok[1] if len(tok) > 1 else "", i, "number of nodes", MIN_NODE_LINE)
    for _ in range(blocks):
        i, tok = _next(lines, scan, "$Nodes")
        n = scan.count(tok[-1], i, "number of nodes in a block", MIN_NODE_LINE)
        for _ in range(n):  # 4.0: "tag x y z" per node; 4.1: n tag lines,
            scan.node(lines)
        for _ in range(0 if version.startswith("4.0") else n):  # then n coordinate lines
            _next(lines, scan, "$Nodes")
    if len(scan.tags) != total:
        raise scan.error(
            f"$Nodes: {len(scan.tags):,} nodes in its blocks, {total:,} in its header",
            "a header count equal to the nodes listed",
        )


def _cells_v4(scan: _Scan, lines, version: str) -> None:
    i, tok = _next(lines, scan, "$Elements")
    blocks = scan.count(tok[0], i, "number of entity blocks", MIN_CELL_LINE)
    scan.count(tok[1] if len(tok) > 1 else "", i, "number of elements", MIN_CELL_LINE)
    for _ in range(blocks):
        i, tok = _next(lines, scan, "$Elements")
        n = scan.count(tok[-1], i, "number of elements in a block", MIN_CELL_LINE)
        for _ in range(n):
            i, t = _next(lines, scan, "$Elements")
            scan.cell(i, t[1:])


def _address_space() -> int:
    """The process's current virtual size in bytes (Linux /proc; 0 if unknown)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


@contextlib.contextmanager
def address_space_cap(size: int) -> Iterator[int]:
    """Cap the address space (RLIMIT_AS, soft) at the current size + the read budget of a
    file of `size` bytes for the `with` block, then restore it; yields the budget in bytes.
    No cap where the current size is unknown or the limit is already lower."""
    budget = READ_BASE_BYTES + READ_BYTES_PER_FILE_BYTE * size
    now = _address_space()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = now + budget
    lower = now > 0 and (soft == resource.RLIM_INFINITY or cap < soft)
    if lower and (hard == resource.RLIM_INFINITY or cap <= hard):
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    else:
        lower = False
    try:
        yield budget
    finally:
        if lower:
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
