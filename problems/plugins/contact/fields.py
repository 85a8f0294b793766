"""The fields of a plug-in's unknowns and their near-null spaces, for the iterative linear path.

`vi_core.krylov` preconditions each field's block with its own multigrid hierarchy; for the
displacement block that hierarchy needs the rigid-body modes (2D: two translations and the
rotation), for the potential block the constant vector is the default.
"""

from __future__ import annotations

import numpy as np

from .bodies import Body


def field_data(bodies: list[Body], free: np.ndarray, n_full: int) -> dict:
    """`MixedVI` keywords fields and near_null: displacement and potential masks over the
    unknowns `free` (full indices), and the displacement block's rigid-body modes (n_disp, 3)."""
    comp = np.full(n_full, -1)  # displacement component of each full dof, −1 = potential
    xy = np.zeros((n_full, 2))  # (n_full, 2) node coordinates of each displacement dof
    for b in bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 2)
        comp[d] = np.arange(2)[None, :]
        xy[d[:, 0]] = xy[d[:, 1]] = b.mesh.points
    c, (x, y) = comp[free], xy[free].T  # (n,) each
    disp = c >= 0
    modes = np.zeros((free.size, 3))  # (n, 3): translations x, y and the rotation (−y, x)
    modes[c == 0, 0] = 1.0
    modes[c == 1, 1] = 1.0
    modes[c == 0, 2] = -y[c == 0]
    modes[c == 1, 2] = x[c == 1]
    fields = {"displacement": disp}
    if (~disp).any():
        fields["potential"] = ~disp
    return {"fields": fields, "near_null": {"displacement": modes[disp]}}
