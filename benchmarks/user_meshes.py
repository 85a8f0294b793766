"""User-like scenes on unstructured gmsh meshes: the test tier the defaults must solve.

    python benchmarks/user_meshes.py OUTDIR [NAME ...]     (needs `pip install gmsh`)

writes OUTDIR/NAME.toml and OUTDIR/meshes/NAME.msh for each scene (all of them without NAME).
The committed copies are in tests/data/user_meshes/ (made by this command: `python
benchmarks/user_meshes.py tests/data/user_meshes`); tests/problems/test_user_meshes.py checks
that they equal what this generator makes where gmsh is installed, validates and solves them.
Each mesh is the coarsest (level 0) mesh a user would bring; `mixvi solve SCENE --level L`
refines it uniformly (a triangle or quadrilateral into 4, a tetrahedron into 8, new boundary
nodes on the file's polylines), and `LEVEL_50K` below is the level at which each scene has
50k–200k unknowns.

The scenes (SI units, m; materials as the shipped scenes use them):

- `actuator_tri`: a PZT-5H actuator with two V-notches in its sides, pressed down and sideways
  onto the convex arc (radius 0.1 m) of an aluminium base; two bodies meshed separately
  (non-matching triangles along the arc), unilateral contact with Coulomb friction, electrodes on
  the actuator's top (0 V) and bottom (100 V).
- `actuator_quad`: the same geometry and data, meshed with quadrilaterals (recombined).
- `punch_graded`: a BaTiO3 T-punch whose stem meets the flange in fillets (radius 3 mm) and
  whose contact corners are rounded (1 mm), on a rigid conductive foundation at 100 V: bilateral
  contact with Tresca friction and the saturated electrical contact law; triangles graded from
  0.3 mm at the fillets and contact ends to 2 mm.
- `cylinder_on_block`: a steel half cylinder (radius 20 mm) pressed onto an aluminium block
  (Hertz-like line contact), triangles graded towards the first touching point, unilateral
  contact with Coulomb friction; the slave is the lower ±40° of the arc.
- `notched_block3d`: a PZT-5H block (poled along z) with a slot across its top and a through
  hole, tetrahedra, on a rigid foundation: bilateral contact with Tresca friction, top electrode
  grounded.
- `punch_on_block3d`: a steel cylindrical punch with a filleted bottom edge (radius 2 mm) on an
  aluminium block, tetrahedra meshed separately: unilateral contact with Coulomb friction through
  the 3D dual mortar, the punch's flat bottom the slave.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

STEEL = '{ kind = "isotropic", E = 2.1e11, nu = 0.3, label = "steel" }'
ALUMINIUM = '{ kind = "isotropic", E = 7.0e10, nu = 0.33, label = "aluminium" }'

#: the level at which each scene has 50k–200k unknowns (tests/problems/test_user_meshes.py
#: checks the count)
LEVEL_50K = {
    "actuator_tri": 3,
    "actuator_quad": 3,
    "punch_graded": 3,
    "cylinder_on_block": 3,
    "notched_block3d": 2,
    "punch_on_block3d": 2,
}


def _geo_outline(gmsh, name: str, parts: list[tuple[str, list]], size: float) -> int:
    """One plane surface of the geo kernel bounded by the named pieces, counterclockwise. A
    piece is a list of ("line", p, q) and ("arc", p, centre, q) items (p, q the end points);
    equal points are one gmsh point, so each body has its own copy of a shared curve. Adds the
    physical surface `name` and a physical curve per piece; returns the surface tag."""
    geo = gmsh.model.geo
    points: dict[tuple[float, float], int] = {}

    def point(p) -> int:
        key = (round(float(p[0]), 12), round(float(p[1]), 12))
        if key not in points:
            points[key] = geo.addPoint(key[0], key[1], 0.0, size)
        return points[key]

    groups: list[tuple[str, list[int]]] = []
    loop = []
    for pname, items in parts:
        tags = []
        for item in items:
            if item[0] == "line":
                tags.append(geo.addLine(point(item[1]), point(item[2])))
            else:
                tags.append(geo.addCircleArc(point(item[1]), point(item[2]), point(item[3])))
        groups.append((pname, tags))
        loop += tags
    surf = geo.addPlaneSurface([geo.addCurveLoop(loop)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surf], name=name)
    for pname, tags in groups:
        gmsh.model.addPhysicalGroup(1, tags, name=pname)
    return surf


def _polyline(*pts) -> list[tuple]:
    """Lines through consecutive points."""
    return [("line", p, q) for p, q in zip(pts[:-1], pts[1:], strict=True)]


def _grade(gmsh, near: str, tags: list[int], sizes: tuple, **distance: float) -> None:
    """The only mesh size: a Threshold field of the Distance (options `distance`) to the
    entities `tags` of kind `near` ("CurvesList", "PointsList"); `sizes` are its (SizeMin,
    SizeMax, DistMin, DistMax)."""
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, near, tags)
    for key, value in distance.items():
        field.setNumber(dist, key, value)
    th = field.add("Threshold")
    field.setNumber(th, "InField", dist)
    for key, value in zip(("SizeMin", "SizeMax", "DistMin", "DistMax"), sizes, strict=True):
        field.setNumber(th, key, value)
    field.setAsBackgroundMesh(th)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)


def _write(gmsh, path: Path, dim: int) -> None:
    gmsh.model.mesh.generate(dim)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(path))


# ---------------------------------------------------------------- 2D: actuator on a curved base

R_ARC = 0.1  # radius of the base's convex top


def _arc_y(x: float) -> float:
    """The base's top (and the actuator's bottom): a circle of radius R_ARC through (0, 0)."""
    return math.sqrt(R_ARC**2 - x**2) - R_ARC


def _actuator(gmsh, path: Path, quads: bool) -> None:
    gmsh.model.add(path.stem)
    c = (0.0, -R_ARC)  # the arc's centre
    a, top, notch_y, notch_d, notch_h = 0.01, 0.008, 0.004, 0.002, 0.0015
    bl, br = (-a, _arc_y(-a)), (a, _arc_y(a))
    _geo_outline(
        gmsh,
        "actuator",
        [
            ("actuator_bottom", [("arc", bl, c, br)]),
            (
                "actuator_right",
                _polyline(br, (a, notch_y - notch_h), (a - notch_d, notch_y),
                          (a, notch_y + notch_h), (a, top)),
            ),
            ("actuator_top", _polyline((a, top), (-a, top))),
            (
                "actuator_left",
                _polyline((-a, top), (-a, notch_y + notch_h), (-a + notch_d, notch_y),
                          (-a, notch_y - notch_h), bl),
            ),
        ],
        0.001,
    )  # fmt: skip
    w, depth = 0.03, -0.012
    _geo_outline(
        gmsh,
        "base",
        [
            ("base_bottom", _polyline((-w, depth), (w, depth))),
            ("base_right", _polyline((w, depth), (w, _arc_y(w)))),
            ("base_top", [("arc", (w, _arc_y(w)), c, (-w, _arc_y(-w)))]),
            ("base_left", _polyline((-w, _arc_y(-w)), (-w, depth))),
        ],
        0.0016,
    )
    if quads:
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.option.setNumber("Mesh.Algorithm", 8)  # frontal-Delaunay for quads
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)  # blossom
        gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 1)  # all quadrilaterals
        gmsh.option.setNumber("Mesh.MeshSizeFactor", 1.8)  # subdivision halves the size
    _write(gmsh, path, 2)


ACTUATOR_TOML = """\
# {comment}
# Made by benchmarks/user_meshes.py; units m, Pa, V.

format = 2

[scene]
title = "{title}"
plugin = "contact"
level = 0

[bodies.actuator]
material = "PZT-5H"
geometry = {{ mesh = "meshes/{name}.msh", body = "actuator" }}

[[bodies.actuator.displacement]]
boundary = "actuator_top"
value = [3.0e-6, -1.0e-5]

[[bodies.actuator.potential]]
boundary = "actuator_top"
value = 0.0

[[bodies.actuator.potential]]
boundary = "actuator_bottom"
value = 100.0

[bodies.base]
material = {aluminium}
geometry = {{ mesh = "meshes/{name}.msh", body = "base" }}

[[bodies.base.displacement]]
boundary = "base_bottom"
value = [0.0, 0.0]

[contact]
slave = "actuator.actuator_bottom"
master = "base.base_top"
law = "unilateral"
friction = "coulomb"
F = 0.3
"""


def actuator_tri(gmsh, path: Path) -> str:
    _actuator(gmsh, path, quads=False)
    return ACTUATOR_TOML.format(
        name=path.stem,
        aluminium=ALUMINIUM,
        title="Notched PZT-5H actuator on a curved aluminium base (triangles, Coulomb)",
        comment="A notched piezoelectric actuator pressed onto the convex arc of an elastic base: "
        "two bodies meshed\n# separately (non-matching triangles), unilateral Coulomb contact.",
    )


def actuator_quad(gmsh, path: Path) -> str:
    _actuator(gmsh, path, quads=True)
    return ACTUATOR_TOML.format(
        name=path.stem,
        aluminium=ALUMINIUM,
        title="Notched PZT-5H actuator on a curved aluminium base (quadrilaterals, Coulomb)",
        comment="actuator_tri meshed with quadrilaterals (gmsh recombination): two bodies, "
        "non-matching\n# along the arc, unilateral Coulomb contact.",
    )


# ---------------------------------------------------------------- 2D: filleted, graded T-punch


def punch_graded(gmsh, path: Path) -> str:
    gmsh.model.add(path.stem)
    a, hs, b, top, r, r2 = 0.008, 0.012, 0.02, 0.02, 0.003, 0.001
    surf = _geo_outline(
        gmsh,
        "punch",
        [
            ("contact", _polyline((-a + r2, 0.0), (a - r2, 0.0))),
            (
                "stem",
                [("arc", (a - r2, 0.0), (a - r2, r2), (a, r2))]
                + _polyline((a, r2), (a, hs - r))
                + [("arc", (a, hs - r), (a + r, hs - r), (a + r, hs))]
                + _polyline((a + r, hs), (b, hs), (b, top)),
            ),
            ("top", _polyline((b, top), (-b, top))),
            (
                "side_left",
                _polyline((-b, top), (-b, hs), (-a - r, hs))
                + [("arc", (-a - r, hs), (-a - r, hs - r), (-a, hs - r))]
                + _polyline((-a, hs - r), (-a, r2))
                + [("arc", (-a, r2), (-a + r2, r2), (-a + r2, 0.0))],
            ),
        ],
        0.002,
    )
    # grade: 0.3 mm at the fillets and the contact's ends, 2 mm from 6 mm away
    arcs = [
        t
        for _, t in gmsh.model.getBoundary([(2, surf)], oriented=False)
        if gmsh.model.getType(1, t) == "Circle"
    ]
    _grade(gmsh, "CurvesList", arcs, (3e-4, 2e-3, 3e-4, 6e-3), Sampling=40)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    _write(gmsh, path, 2)
    return f"""\
# A BaTiO3 T-punch with filleted corners on a rigid conductive foundation: bilateral contact
# with Tresca friction and the saturated electrical contact law (foundation at 100 V); a graded
# triangle mesh (0.3 mm at the fillets, 2 mm away from them).
# Made by benchmarks/user_meshes.py; units m, Pa, V, C, F/m².

format = 2

[scene]
title = "Filleted BaTiO3 T-punch, graded triangles, on a rigid conductive foundation (Tresca)"
plugin = "contact"
level = 0

[bodies.punch]
material = "BaTiO3"
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "punch" }}

[[bodies.punch.displacement]]
boundary = "top"
value = [2.0e-6, -5.0e-6]

[[bodies.punch.potential]]
boundary = "top"
value = 0.0

[contact]
slave = "punch.contact"
master = "rigid"
g = 2.0e7

[contact.electrical]
kind = "conductive"
phi_F = 100.0
law = "saturated"
k0 = 2.0e-6
lambda_star = 2.0e8
"""


# ---------------------------------------------------------------- 2D: cylinder on a block


def cylinder_on_block(gmsh, path: Path) -> str:
    gmsh.model.add(path.stem)
    rad, half = 0.02, math.radians(40.0)
    c = (0.0, rad)
    left, right = (-rad, rad), (rad, rad)
    cl = (-rad * math.sin(half), rad - rad * math.cos(half))
    cr = (rad * math.sin(half), rad - rad * math.cos(half))
    _geo_outline(
        gmsh,
        "cylinder",
        [
            ("cylinder_free_left", [("arc", left, c, cl)]),
            ("cylinder_contact", [("arc", cl, c, cr)]),
            ("cylinder_free_right", [("arc", cr, c, right)]),
            ("cylinder_top", _polyline(right, left)),
        ],
        0.002,
    )
    w, depth = 0.04, -0.03
    _geo_outline(
        gmsh,
        "block",
        [
            ("block_bottom", _polyline((-w, depth), (w, depth))),
            ("block_right", _polyline((w, depth), (w, 0.0))),
            ("block_top", _polyline((w, 0.0), (-w, 0.0))),
            ("block_left", _polyline((-w, 0.0), (-w, depth))),
        ],
        0.004,
    )
    # grade both bodies towards the first touching point (0, 0): 0.4 mm there
    touch = gmsh.model.geo.addPoint(0.0, 0.0, 0.0)
    gmsh.model.geo.synchronize()
    _grade(gmsh, "PointsList", [touch], (4e-4, 4e-3, 2e-3, 0.03))
    _write(gmsh, path, 2)
    return f"""\
# A steel half cylinder (radius 20 mm) pressed down and sideways onto an aluminium block
# (Hertz-like line contact): two bodies meshed separately with triangles graded towards the
# first touching point, unilateral contact with Coulomb friction; the slave is the lower ±40°
# of the arc. Made by benchmarks/user_meshes.py; units m, Pa.

format = 2

[scene]
title = "Steel half cylinder on an aluminium block, graded triangles (Hertz-like, Coulomb)"
plugin = "contact"
level = 0

[bodies.cylinder]
material = {STEEL}
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "cylinder" }}

[[bodies.cylinder.displacement]]
boundary = "cylinder_top"
value = [5.0e-6, -4.0e-5]

[bodies.block]
material = {ALUMINIUM}
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "block" }}

[[bodies.block.displacement]]
boundary = "block_bottom"
value = [0.0, 0.0]

[contact]
slave = "cylinder.cylinder_contact"
master = "block.block_top"
law = "unilateral"
friction = "coulomb"
F = 0.2
"""


# ---------------------------------------------------------------- 3D


def _faces(gmsh, test: Callable[[list[float]], bool]) -> list[int]:
    """The surfaces whose bounding box passes `test` (gmsh pads boxes by about 1e-7)."""
    return [t for _, t in gmsh.model.getEntities(2) if test(gmsh.model.getBoundingBox(2, t))]


def notched_block3d(gmsh, path: Path) -> str:
    gmsh.model.add(path.stem)
    occ = gmsh.model.occ
    lx, ly, lz = 0.02, 0.01, 0.01
    block = occ.addBox(0, 0, 0, lx, ly, lz)
    slot = occ.addBox(0.0095, -0.001, 0.006, 0.001, ly + 0.002, 0.005)
    hole = occ.addCylinder(0.005, -0.001, 0.004, 0, ly + 0.002, 0, 0.0015)
    body, _ = occ.cut([(3, block)], [(3, slot), (3, hole)])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [t for _, t in body], name="block")
    eps = 1e-6
    named = {
        "bottom": lambda b: b[5] < eps,
        "top": lambda b: b[2] > lz - eps,
        "left": lambda b: b[3] < eps,
        "right": lambda b: b[0] > lx - eps,
    }
    for name, test in named.items():
        gmsh.model.addPhysicalGroup(2, _faces(gmsh, test), name=name)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.0018)
    _write(gmsh, path, 3)
    return f"""\
# A PZT-5H block (poled along z) with a slot across its top and a through hole, meshed with
# tetrahedra, on a rigid foundation: bilateral contact with Tresca friction on its bottom, its
# top clamped to a plate pushed down and sideways, top electrode grounded.
# Made by benchmarks/user_meshes.py; units m, Pa, V.

format = 2

[scene]
title = "Notched PZT-5H block (tetrahedra) on a rigid foundation (Tresca, 3D)"
plugin = "contact"
level = 0

[bodies.block]
material = {{ name = "PZT-5H", poling = [0.0, 0.0, 1.0] }}
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "block" }}

[[bodies.block.displacement]]
boundary = "top"
value = [2.0e-6, 1.0e-6, -4.0e-6]

[[bodies.block.potential]]
boundary = "top"
value = 0.0

[contact]
slave = "block.bottom"
master = "rigid"
g = 2.0e7
"""


def punch_on_block3d(gmsh, path: Path) -> str:
    gmsh.model.add(path.stem)
    occ = gmsh.model.occ
    rad, height, fillet = 0.008, 0.012, 0.002
    punch = occ.addCylinder(0, 0, 0, 0, 0, height, rad)
    occ.synchronize()
    bottom_edge = [
        t
        for _, t in gmsh.model.getEntities(1)
        if gmsh.model.getBoundingBox(1, t)[5] < 1e-6  # the circle at z = 0
    ]
    punch_vol = occ.fillet([punch], bottom_edge, [fillet])
    w, depth = 0.02, 0.015
    block = occ.addBox(-w, -w, -depth, 2 * w, 2 * w, depth)
    occ.synchronize()
    (pv,) = [t for _, t in punch_vol]
    gmsh.model.addPhysicalGroup(3, [pv], name="punch")
    gmsh.model.addPhysicalGroup(3, [block], name="block")
    eps = 1e-6
    punch_faces = {t for _, t in gmsh.model.getBoundary([(3, pv)], oriented=False)}
    block_faces = {t for _, t in gmsh.model.getBoundary([(3, block)], oriented=False)}

    def pick(faces: set[int], test) -> list[int]:
        return sorted(t for t in faces if test(gmsh.model.getBoundingBox(2, t)))

    flat = pick(punch_faces, lambda b: b[5] < eps and b[2] > -eps)  # the disc at z = 0
    top = pick(punch_faces, lambda b: b[2] > height - eps)
    gmsh.model.addPhysicalGroup(2, flat, name="punch_contact")
    gmsh.model.addPhysicalGroup(2, top, name="punch_top")
    gmsh.model.addPhysicalGroup(2, pick(block_faces, lambda b: b[2] > -eps), name="block_top")
    gmsh.model.addPhysicalGroup(
        2, pick(block_faces, lambda b: b[5] < -depth + eps), name="block_bottom"
    )
    gmsh.model.mesh.setSize(gmsh.model.getBoundary([(3, pv)], recursive=True), 0.0022)
    gmsh.model.mesh.setSize(gmsh.model.getBoundary([(3, block)], recursive=True), 0.005)
    _write(gmsh, path, 3)
    return f"""\
# A steel cylindrical punch (radius 8 mm) with a filleted bottom edge (radius 2 mm) pressed down
# and sideways onto an aluminium block: two bodies meshed separately with tetrahedra, unilateral
# contact with Coulomb friction through the 3D dual mortar, the punch's flat bottom the slave.
# Made by benchmarks/user_meshes.py; units m, Pa.

format = 2

[scene]
title = "Steel punch with a filleted edge on an aluminium block (tetrahedra, Coulomb, 3D)"
plugin = "contact"
level = 0

[bodies.punch]
material = {STEEL}
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "punch" }}

[[bodies.punch.displacement]]
boundary = "punch_top"
value = [3.0e-6, 1.0e-6, -1.0e-5]

[bodies.block]
material = {ALUMINIUM}
geometry = {{ mesh = "meshes/{path.stem}.msh", body = "block" }}

[[bodies.block.displacement]]
boundary = "block_bottom"
value = [0.0, 0.0, 0.0]

[contact]
slave = "punch.punch_contact"
master = "block.block_top"
law = "unilateral"
friction = "coulomb"
F = 0.3
"""


SCENES: dict[str, Callable] = {
    "actuator_tri": actuator_tri,
    "actuator_quad": actuator_quad,
    "punch_graded": punch_graded,
    "cylinder_on_block": cylinder_on_block,
    "notched_block3d": notched_block3d,
    "punch_on_block3d": punch_on_block3d,
}


def generate(out: Path, names: list[str] | None = None) -> list[Path]:
    """Write OUT/NAME.toml and OUT/meshes/NAME.msh for each scene in `names` (default all);
    return the scene files."""
    import gmsh

    (out / "meshes").mkdir(parents=True, exist_ok=True)
    written = []
    for name in names or list(SCENES):
        gmsh.initialize(["-noenv"])
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)  # the same mesh on every machine
        try:
            toml = SCENES[name](gmsh, out / "meshes" / f"{name}.msh")
        finally:
            gmsh.finalize()
        scene = out / f"{name}.toml"
        scene.write_text(toml)
        written.append(scene)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="folder for NAME.toml and meshes/NAME.msh")
    parser.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help=f"scenes to make (default all: {', '.join(SCENES)})",
    )
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in SCENES]
    if unknown:
        parser.error(f"NAME {', '.join(unknown)}: expected one of {', '.join(SCENES)}")
    for scene in generate(args.out, args.names or None):
        print(scene)
    return 0


if __name__ == "__main__":
    sys.exit(main())
