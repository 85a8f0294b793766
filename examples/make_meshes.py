"""Make the shipped example meshes with the gmsh Python API (optional: `pip install gmsh`).

    python examples/make_meshes.py [OUTDIR]     (default problems/scenes/meshes)

The .msh files are committed, so running mixvi never needs gmsh; this script documents how they
were made and remakes them. Physical groups carry the names the scenes use:

- `wavy_two_body.msh` (gmsh v4.1, triangles): a `punch` (slave) on a `base` (master) along the
  non-circular curve y = 0.5 + 0.08 sin(1.5πx), x ∈ [−1, 1]. The two bodies are meshed
  separately (each has its own copy of the interface curve, mesh sizes 0.1 and 0.07), so their
  interface nodes do not match and the two polylines differ by the chord sagitta. Curves:
  punch_top, punch_left, punch_right, punch_contact; base_bottom, base_left, base_right,
  base_contact.
- `plate_with_hole.msh` (gmsh v2.2, quadrilaterals): a `plate` [0, 2] × [0, 1] with a circular
  hole of radius 0.25 about (1, 0.5). Curves: bottom, right, top, left, hole.
- `bracket3d.msh` (gmsh v4.1, tetrahedra): an L-shaped `bracket` (OpenCASCADE): a foot
  [0, 0.6] × [0, 0.4] × [0, 0.08] with a bolt hole of radius 0.08 about (0.35, 0.2) and a wall
  [0, 0.08] × [0, 0.4] × [0, 0.5], mesh size 0.06. Surfaces: base (the foot's bottom z = 0),
  top (the wall's top z = 0.5), bolt (the hole), toe (x = 0.6), back (x = 0).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "problems" / "scenes" / "meshes"


def interface(x: np.ndarray) -> np.ndarray:
    """The punch/base interface y(x)."""
    return 0.5 + 0.08 * np.sin(1.5 * np.pi * x)


def _body(gmsh, name: str, outline: list[tuple[str, list]], size: float) -> None:
    """One plane surface of the geo kernel bounded by the named curves, in order (each a list
    of points: two make a line, more a spline through them); shared end points are one point."""
    geo = gmsh.model.geo
    point_tags: dict[tuple[float, float], int] = {}

    def point(p) -> int:
        key = (round(float(p[0]), 12), round(float(p[1]), 12))
        if key not in point_tags:
            point_tags[key] = geo.addPoint(key[0], key[1], 0.0, size)
        return point_tags[key]

    curves = []
    for _, pts in outline:
        tags = [point(p) for p in pts]
        curves.append(geo.addSpline(tags) if len(tags) > 2 else geo.addLine(*tags))
    surf = geo.addPlaneSurface([geo.addCurveLoop(curves)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surf], name=name)
    for c, (cname, _) in zip(curves, outline, strict=True):
        gmsh.model.addPhysicalGroup(1, [c], name=cname)


def wavy_two_body(gmsh, path: Path) -> None:
    gmsh.model.add("wavy_two_body")
    xs = np.linspace(-1.0, 1.0, 41)
    wave = [(x, y) for x, y in zip(xs, interface(xs), strict=True)]
    # punch: interface left → right is its bottom (counterclockwise), then right, top, left
    _body(
        gmsh,
        "punch",
        [
            ("punch_contact", wave),
            ("punch_right", [wave[-1], (1.0, 1.0)]),
            ("punch_top", [(1.0, 1.0), (-1.0, 1.0)]),
            ("punch_left", [(-1.0, 1.0), wave[0]]),
        ],
        0.1,
    )
    _body(
        gmsh,
        "base",
        [
            ("base_bottom", [(-1.0, 0.0), (1.0, 0.0)]),
            ("base_right", [(1.0, 0.0), wave[-1]]),
            ("base_contact", wave[::-1]),
            ("base_left", [wave[0], (-1.0, 0.0)]),
        ],
        0.07,
    )
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(path))


def plate_with_hole(gmsh, path: Path) -> None:
    gmsh.model.add("plate_with_hole")
    geo = gmsh.model.geo
    h = 0.2  # subdivision into quadrilaterals halves it
    c = [geo.addPoint(x, y, 0, h) for x, y in ((0, 0), (2, 0), (2, 1), (0, 1))]
    sides = [geo.addLine(c[i], c[(i + 1) % 4]) for i in range(4)]
    centre = geo.addPoint(1.0, 0.5, 0, h)
    ring = [geo.addPoint(1 + 0.25 * np.cos(a), 0.5 + 0.25 * np.sin(a), 0, h / 2) for a in
            np.pi / 2 * np.arange(4)]  # fmt: skip
    arcs = [geo.addCircleArc(ring[i], centre, ring[(i + 1) % 4]) for i in range(4)]
    outer, inner = geo.addCurveLoop(sides), geo.addCurveLoop(arcs)
    surf = geo.addPlaneSurface([outer, inner])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surf], name="plate")
    for tag, name in zip(sides, ("bottom", "right", "top", "left"), strict=True):
        gmsh.model.addPhysicalGroup(1, [tag], name=name)
    gmsh.model.addPhysicalGroup(1, arcs, name="hole")
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.option.setNumber("Mesh.Algorithm", 8)  # frontal-Delaunay for quads
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)  # blossom
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 1)  # all quadrilaterals
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.write(str(path))


def bracket3d(gmsh, path: Path) -> None:
    gmsh.model.add("bracket3d")
    occ = gmsh.model.occ
    foot = occ.addBox(0, 0, 0, 0.6, 0.4, 0.08)
    wall = occ.addBox(0, 0, 0, 0.08, 0.4, 0.5)
    hole = occ.addCylinder(0.35, 0.2, -0.1, 0, 0, 0.3, 0.08)
    body, _ = occ.fuse([(3, foot)], [(3, wall)])
    body, _ = occ.cut(body, [(3, hole)])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [t for _, t in body], name="bracket")

    def faces(test) -> list[int]:  # the surfaces whose bounding box passes `test`
        return [t for _, t in gmsh.model.getEntities(2) if test(gmsh.model.getBoundingBox(2, t))]

    eps = 1e-6
    named = {
        "base": lambda b: b[5] < eps,  # z_max = 0
        "top": lambda b: b[2] > 0.5 - eps,  # z_min = 0.5
        "toe": lambda b: b[0] > 0.6 - eps,  # x_min = 0.6
        "back": lambda b: b[3] < eps,  # x_max = 0
        "bolt": lambda b: b[0] > 0.27 - eps and b[3] < 0.43 + eps and b[2] < eps
        and b[5] > 0.08 - eps,  # the hole's wall
    }  # fmt: skip
    for name, test in named.items():
        gmsh.model.addPhysicalGroup(2, faces(test), name=name)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 0.06)
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(path))


def main(argv: list[str]) -> int:
    import gmsh

    out = Path(argv[0]) if argv else OUT
    out.mkdir(parents=True, exist_ok=True)
    for make, name in (
        (wavy_two_body, "wavy_two_body.msh"),
        (plate_with_hole, "plate_with_hole.msh"),
        (bracket3d, "bracket3d.msh"),
    ):
        gmsh.initialize(["-noenv"])
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            make(gmsh, out / name)
        finally:
            gmsh.finalize()
        print(out / name)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
