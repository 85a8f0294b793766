"""Sizes of a contact scene's levels counted on its level-0 meshes (contract v2 `count`), for
both fronts: nothing finer than level 0 is meshed, nothing is assembled.

(unknowns n + m, stored entries of A, n) per level from the free unknowns of each coarse
entity (`bodies.free_per_entity`, `fem.refined_counts`: exact for triangles, quadrilaterals
and hexahedra; tetrahedra's entries within its stated bound) and, for m, the free displacement
components of the slave boundary's nodes: the crosspoint rules give a contact node d − p rows
(d the dimension, p its prescribed components; `curve_contact.carrying`,
`surface_contact.carrying`). A 2D two-body interface also leaves the slave nodes whose support
the master does not cover without rows (`curve_contact.slave_contact`); those are not counted
here, so m is then over-counted by them (none in the shipped scenes: every 2D shipped scene's
count equals its built sizes at levels 0 and 1, tests/problems/plugins/contact/test_plugin.py)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fem.refined_counts import Skeleton
from problems.scene import SceneModel

from ..contract import check_meshed
from .bodies import Body, free_per_entity


def sizes(spec: SceneModel, levels: Sequence[int]) -> list[tuple[int, int, int]]:
    """(unknowns n + m, nnz(A), n) of each of `levels` of the validated contact scene `spec`
    (module docstring), the level-0 meshes meshed once for all the levels."""
    slave = spec.contact.slave.split(".", 1) if spec.contact is not None else None
    parts = []  # per body: (skeleton, free unknowns per entity, slave displacements or None)
    for name, tb in spec.bodies.items():
        mesh = tb.geometry.mesh(0)
        if tb.geometry.BOUNDARIES is None:
            check_meshed(mesh, tb.boundary_refs())
        body = Body(name, mesh, tb.material.material(mesh.points.shape[1]), 0)
        skeleton = Skeleton(mesh)
        disp, pot = free_per_entity(tb, body, skeleton)  # (n_entities,) each
        on_slave = None
        if slave is not None and slave[0] == name:
            check_meshed(mesh, [("contact.slave", slave[1])])
            on = skeleton.closure(mesh.boundaries[slave[1]])  # (n_entities,)
            on_slave = np.where(on, disp, 0)  # (n_entities,)
        parts.append((skeleton, disp + pot, on_slave))
    levels = list(levels)
    n, nnz, m = np.zeros((3, len(levels)), dtype=np.int64)  # per level
    for skeleton, free, on_slave in parts:
        n_nnz = np.array(skeleton.sums(free, levels), dtype=np.int64)  # (levels, 2)
        n, nnz = n + n_nnz[:, 0], nnz + n_nnz[:, 1]
        if on_slave is not None:
            m = np.array([s[0] for s in skeleton.sums(on_slave, levels, pairs=False)])
    return [(int(a + c), int(b), int(a)) for a, b, c in zip(n, nnz, m, strict=True)]
