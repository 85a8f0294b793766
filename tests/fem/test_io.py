"""VTU output."""

import meshio
import numpy as np
import pytest

from fem.io import write_vtu
from fem.meshing import rectangle


@pytest.mark.parametrize("element", ["quad", "triangle"])
def test_write_vtu_round_trip(tmp_path, element):
    mesh = rectangle((0.0, 2.0), (0.0, 1.0), (3, 2), element)
    rng = np.random.default_rng(0)
    u = rng.normal(size=2 * mesh.n_nodes)  # interleaved dof vector
    phi = rng.normal(size=mesh.n_nodes)
    sigma = rng.normal(size=(mesh.n_cells, 3))
    D = rng.normal(size=(mesh.n_cells, 2))
    path = tmp_path / "out.vtu"
    write_vtu(path, mesh, point_data={"u": u, "phi": phi}, cell_data={"sigma": sigma, "D": D})
    back = meshio.read(path)
    assert np.allclose(back.points[:, :2], mesh.points) and np.allclose(back.points[:, 2], 0)
    assert back.cells[0].type == element
    assert np.array_equal(back.cells[0].data, mesh.cells)
    assert np.allclose(back.point_data["u"], np.c_[u.reshape(-1, 2), np.zeros(mesh.n_nodes)])
    assert np.allclose(back.point_data["phi"].ravel(), phi)
    assert np.allclose(back.cell_data["sigma"][0], sigma)
    assert np.allclose(back.cell_data["D"][0], np.c_[D, np.zeros(mesh.n_cells)])


def test_write_vtu_without_data_and_bad_field(tmp_path):
    mesh = rectangle((0.0, 1.0), (0.0, 1.0), (2, 2))
    write_vtu(tmp_path / "m.vtu", mesh)
    assert meshio.read(tmp_path / "m.vtu").points.shape == (9, 3)
    with pytest.raises(ValueError, match="'phi'"):
        write_vtu(tmp_path / "bad.vtu", mesh, point_data={"phi": np.zeros(5)})
