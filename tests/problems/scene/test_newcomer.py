"""Acceptance (issue 15): a newcomer with a gmsh file of their own part (named physical groups)
solves a frictional contact problem on it with one command and opens the result and the
contact line in ParaView — here read back with meshio.

The part is `data/bracket.msh`, made by `make_bracket` below with gmsh (an L-shaped bracket
with a hole, triangles, gmsh v4.1); it is committed so the test needs no gmsh.
"""

import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest

from tests import optional

DATA = Path(__file__).resolve().parent / "data"
SCENE = """\
format = 2

[scene]
title = "My bracket on a rigid floor"
plugin = "contact"
level = 1

[bodies.bracket]
material = { kind = "isotropic", E = 7.0e10, nu = 0.33 }
geometry = { mesh = "bracket.msh", body = "bracket" }

[[bodies.bracket.displacement]]
boundary = "wall"
value = [2.0e-4, -1.0e-4]

[contact]
slave = "bracket.foot"
master = "rigid"
g = 2.0e7
"""


def make_bracket(path):
    """The newcomer's own part (gmsh API, OCC kernel): an L-shaped bracket, 0.6 m × 0.4 m with
    a 0.3 m × 0.2 m notch cut from its upper right, a hole of radius 0.06 m, meshed with
    triangles of size 0.05 (gmsh v4.1). Physical groups: surface 'bracket'; curves 'foot'
    (the bottom, on the foundation), 'wall' (the left side, pushed), 'hole', 'free' (the rest)."""
    import gmsh

    gmsh.initialize(["-v", "0"])
    try:
        gmsh.model.add("bracket")
        occ = gmsh.model.occ
        outer = occ.addRectangle(0, 0, 0, 0.6, 0.4)
        notch = occ.addRectangle(0.3, 0.2, 0, 0.3, 0.2)
        hole = occ.addDisk(0.15, 0.2, 0, 0.06, 0.06)
        (surf,), _ = occ.cut([(2, outer)], [(2, notch), (2, hole)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [surf[1]], name="bracket")
        groups = {"foot": [], "wall": [], "hole": [], "free": []}
        for _, c in gmsh.model.getBoundary([surf], oriented=False):
            x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(1, c)
            if y1 < 1e-6:  # gmsh pads bounding boxes by about 1e-7
                groups["foot"].append(c)
            elif x1 < 1e-6:
                groups["wall"].append(c)
            elif x0 > 0.05 and x1 < 0.25 and y0 > 0.1 and y1 < 0.3:
                groups["hole"].append(c)
            else:
                groups["free"].append(c)
        for name, tags in groups.items():
            gmsh.model.addPhysicalGroup(1, tags, name=name)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.05)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _mixvi() -> str:
    """The installed `mixvi` command of this environment."""
    exe = Path(sys.executable).parent / "mixvi"
    return str(exe) if exe.exists() else shutil.which("mixvi")


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    d = tmp_path_factory.mktemp("newcomer")
    shutil.copy(DATA / "bracket.msh", d / "bracket.msh")
    (d / "bracket.toml").write_text(SCENE)
    run = subprocess.run(
        [_mixvi(), "solve", "bracket.toml"], cwd=d, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stderr
    return d, d / "out" / "bracket", run.stdout


def test_one_command_solves_the_part_and_says_so(solved):
    _, out, stdout = solved
    assert "converged in" in stdout and "contact:" in stdout and "force on the slave" in stdout
    assert (out / "summary.json").is_file()


def test_the_result_and_the_contact_line_read_back(solved):
    d, out, _ = solved
    body = meshio.read(out / "bracket.vtu")
    n = len(body.points)
    assert body.point_data["displacement"].shape == (n, 3)
    stress = body.cell_data["stress"][0]
    assert stress.shape[1] == 6 and np.isfinite(stress).all()
    # the contact line: the nodes of the file's 'foot' group, refined once (level 1)
    mesh = meshio.read(d / "bracket.msh")
    tag = mesh.field_data["foot"][0]
    foot = np.concatenate(
        [
            c.data
            for c, t in zip(mesh.cells, mesh.cell_data["gmsh:physical"], strict=True)
            if c.type == "line" and (t == tag).all()
        ]
    )
    line = meshio.read(out / "contact.vtu")
    assert len(line.points) == 2 * len(foot) + 1  # every foot segment split in two
    np.testing.assert_allclose(line.points[:, 1], 0.0, atol=1e-12)  # on the floor y = 0
    assert line.points[:, 0].min() == pytest.approx(0.0) and line.points[
        :, 0
    ].max() == pytest.approx(0.6)
    states = line.point_data["state"]
    assert set(np.unique(states)) <= {0, 1, 3}  # stick, slip, no_multiplier (the clamped corner)
    lam_n = line.point_data["lambda_n"]
    assert np.nanmax(lam_n) > 0  # pressed onto the floor
    files = [ds.get("file") for ds in ET.parse(out / "results.pvd").getroot().iter("DataSet")]
    assert files == ["bracket.vtu", "estimate_bracket.vtu", "contact.vtu"]  # estimate: per cell


def test_the_committed_bracket_is_what_make_bracket_makes(tmp_path):
    optional.gmsh()
    make_bracket(tmp_path / "bracket.msh")
    a, b = meshio.read(tmp_path / "bracket.msh"), meshio.read(DATA / "bracket.msh")
    assert sorted(a.field_data) == sorted(b.field_data)
    assert len(a.points) == len(b.points)
    np.testing.assert_allclose(np.sort(a.points, axis=0), np.sort(b.points, axis=0), atol=1e-9)
