"""examples/make_meshes.py remakes the shipped meshes (gmsh optional: skipped without it)."""

import importlib.util
from pathlib import Path

from fem.mesh_import import body_mesh, read_mesh
from tests import optional

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "problems" / "scenes" / "meshes"


def test_the_mesh_script_makes_the_shipped_meshes(tmp_path):
    optional.gmsh()
    spec = importlib.util.spec_from_file_location(
        "make_meshes", ROOT / "examples" / "make_meshes.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main([str(tmp_path)]) == 0
    for name, bodies in (("wavy_two_body", ("punch", "base")), ("plate_with_hole", ("plate",))):
        made, shipped = read_mesh(tmp_path / f"{name}.msh"), read_mesh(SHIPPED / f"{name}.msh")
        assert made.groups.keys() == shipped.groups.keys()
        for b in bodies:
            m, s = body_mesh(made, b), body_mesh(shipped, b)
            assert (m.cell_type, sorted(m.boundaries)) == (s.cell_type, sorted(s.boundaries))
            assert abs(m.n_cells - s.n_cells) <= 0.05 * s.n_cells  # gmsh versions may differ
    made = body_mesh(read_mesh(tmp_path / "bracket3d.msh", planar=False), "bracket")
    shipped = body_mesh(read_mesh(SHIPPED / "bracket3d.msh", planar=False), "bracket")
    assert (made.cell_type, sorted(made.boundaries)) == (
        shipped.cell_type,
        sorted(shipped.boundaries),
    )
    assert abs(made.n_cells - shipped.n_cells) <= 0.05 * shipped.n_cells
