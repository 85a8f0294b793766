"""The per-body VTU fields and files (`write_bodies`) of a contact solve, 2D or 3D, named for
ParaView users (docs/design.md, "Results"; docs/fem3d.md, "Contact: results").

Point data: displacement (m; 2 components in 2D, 3 in 3D), electric_potential (V). Cell data
(at the centroids): stress (Pa, a symmetric tensor in VTK order XX, YY, ZZ, XY, YZ, XZ),
von_mises (Pa), electric_field = −∇φ (V/m), electric_displacement (C/m²). In 2D, σ_zz (plane
strain, ε_zz = 0) needs constants beyond the in-plane C (`Material.C_zz`); where a material
lacks them the ZZ component is NaN, von_mises is not written and the returned note says why.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fem import assembly
from fem.io import write_vtu
from problems.output.results import VTK_ORDER, von_mises


def body_fields(body, x_body: np.ndarray) -> tuple[dict, dict, str | None]:
    """(point_data, cell_data, note) of one body (2D or 3D) from its full vector; note is None
    or the reason σ_zz and von_mises are missing (2D only)."""
    u, phi = body.split(x_body)  # (N, d), (N,) or None
    m = body.material
    sigma, D = assembly.cell_fields(body.mesh, u.ravel(), phi, m.C, m.e, m.kappa)  # (nc, v)
    eps, grad_phi = assembly.cell_gradients(body.mesh, u.ravel(), phi)  # (nc, v), (nc, d)
    note = None
    if sigma.shape[1] == 3:  # plane strain (xx, yy, xy): complete to Voigt 6 with σ_zz
        if m.C_zz is None or (phi is not None and m.e_zz is None):
            szz = np.full(sigma.shape[0], np.nan)
            note = (
                f"body {body.name!r}: material {m.name!r} gives only the in-plane constants, so "
                "sigma_zz (plane strain) is unknown: stress ZZ is NaN and von_mises is omitted "
                "(named materials and isotropic ones carry the full constants)"
            )
        else:
            szz = eps @ m.C_zz  # (nc,)
            if phi is not None:
                szz = szz + grad_phi @ m.e_zz
        z = np.zeros_like(szz)
        sigma = np.stack([sigma[:, 0], sigma[:, 1], szz, z, z, sigma[:, 2]], axis=1)  # (nc, 6)
    point = {"displacement": u}
    cell = {"stress": sigma[:, VTK_ORDER]}
    if note is None:
        cell["von_mises"] = von_mises(sigma)
    if phi is not None:
        point["electric_potential"] = phi
        cell["electric_field"] = -grad_phi
        cell["electric_displacement"] = D
    return point, cell, note


def write_bodies(model, x_full: np.ndarray, outdir: Path) -> tuple[list[str], list[str]]:
    """(files, notes): BODY.vtu of every body's fields (`body_fields`) and their notes."""
    files, notes = [], []
    for b in model.bodies:
        point, cell, note = body_fields(b, x_full[b.offset : b.offset + b.size])
        write_vtu(outdir / f"{b.name}.vtu", b.mesh, point, cell)
        files.append(f"{b.name}.vtu")
        notes += [note] if note else []
    return files, notes
