"""fem.mesh_bounds: a mesh file is checked before meshio allocates from it — each bound
refuses its case, and each removed bound lets that case through (mutation tests)."""

from __future__ import annotations

import os
import resource

import pytest

from fem import mesh_bounds
from fem.mesh_import import MeshImportError, body_mesh, read_mesh
from fem.meshing import rectangle
from tests.gmsh_files import write_msh


def _msh(tmp_path, fmt="gmsh22"):
    p = tmp_path / "m.msh"
    write_msh(p, {"part": rectangle((0, 2), (0, 1), (3, 2))}, fmt)
    return p


def _edit_node(p, k: int, text: str) -> None:
    lines = p.read_text().split("\n")
    i = lines.index("$Nodes")
    lines[i + 1 + k] = text
    p.write_text("\n".join(lines))


def test_a_valid_file_passes_every_bound(tmp_path):
    for fmt in ("gmsh22", "gmsh"):
        assert body_mesh(read_mesh(_msh(tmp_path, fmt)), "part").n_nodes == 12


@pytest.mark.parametrize(
    "k, text, needle",
    [
        (1, "1000000000 0 0 0", "node tag 1000000000"),
        (1, "0 0 0 0", "node tag 0"),
        (2, "1 0.6666666666666666 0 0", "node tag 1 given 2 times"),
        (0, "100000000000", "number of nodes"),
        (0, "seven", "an integer"),
    ],
)
def test_gmsh_v2_tags_and_counts_are_refused(tmp_path, k, text, needle):
    p = _msh(tmp_path)
    _edit_node(p, k, text)
    with pytest.raises(MeshImportError, match=needle):
        read_mesh(p)


def test_gmsh_v4_huge_tag_is_refused(tmp_path):
    p = _msh(tmp_path, "gmsh")
    lines = p.read_text().split("\n")
    i = lines.index("$Nodes")
    j = next(k for k in range(i + 3, len(lines)) if lines[k].strip().isdigit())
    lines[j] = "1000000000"  # the first node tag of the first block
    p.write_text("\n".join(lines))
    with pytest.raises(MeshImportError, match="node tag 1000000000"):
        read_mesh(p)


def test_a_cell_naming_a_missing_tag_is_refused(tmp_path):
    p = _msh(tmp_path)
    lines = p.read_text().split("\n")
    i = lines.index("$Elements") + 2
    lines[i] = " ".join([*lines[i].split()[:-1], "99"])
    p.write_text("\n".join(lines))
    with pytest.raises(MeshImportError, match="node tag 99, which no node has"):
        read_mesh(p)


@pytest.mark.parametrize(
    "make, needle",
    [
        (os.mkfifo, "named pipe"),
        (lambda p: p.symlink_to("/dev/zero"), "a device"),
        (lambda p: p.mkdir(), "a folder"),
    ],
    ids=["fifo", "dev-zero", "folder"],
)
def test_only_regular_files_are_read(tmp_path, make, needle):
    p = tmp_path / "m.msh"
    make(p)
    with pytest.raises(MeshImportError, match=needle):
        read_mesh(p)


def test_a_file_above_the_size_bound_is_refused_before_reading(tmp_path):
    p = tmp_path / "m.msh"
    with open(p, "wb") as fh:
        fh.truncate(mesh_bounds.MAX_FILE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(MeshImportError, match="at most"):
        read_mesh(p)


def test_huge_coordinates_are_refused(tmp_path):
    p = _msh(tmp_path)
    _edit_node(p, 5, "5 1e300 0.5 0")
    with pytest.raises(MeshImportError, match="magnitude at most"):
        read_mesh(p)


def test_the_address_space_cap_turns_a_blow_up_into_a_refusal(tmp_path, monkeypatch):
    """With the ASCII scan removed, meshio's tag-long array meets the cap: MemoryError →
    refusal; the process's limit is restored afterwards."""
    p = _msh(tmp_path)
    _edit_node(p, 1, "1000000000 0 0 0")
    monkeypatch.setattr(mesh_bounds, "scan_gmsh_ascii", lambda *a: None)
    before = resource.getrlimit(resource.RLIMIT_AS)
    with pytest.raises(MeshImportError, match="reading it needs more than"):
        read_mesh(p)
    assert resource.getrlimit(resource.RLIMIT_AS) == before


def test_mutation_without_the_tag_check_a_duplicate_is_misread(tmp_path, monkeypatch):
    """Removing the tag check lets a duplicate node tag through to meshio, which silently
    overwrites a node: the refusal is gone (read_mesh returns or says something else)."""
    p = _msh(tmp_path)
    _edit_node(p, 2, "1 0.6666666666666666 0 0")
    monkeypatch.setattr(mesh_bounds._Scan, "check", lambda self: None)
    try:
        body_mesh(read_mesh(p), "part")
    except MeshImportError as err:
        assert "given 2 times" not in str(err)


def test_mutation_without_the_count_bound_meshio_allocates(tmp_path, monkeypatch):
    """With the scan removed the count reaches meshio, which asks for the memory: the
    refusal (the cap's, or meshio's own) no longer names the count."""
    p = _msh(tmp_path)
    _edit_node(p, 0, "100000000000")
    monkeypatch.setattr(mesh_bounds, "scan_gmsh_ascii", lambda *a: None)
    with pytest.raises(MeshImportError) as err:
        read_mesh(p)
    assert "number of nodes" not in str(err.value)
