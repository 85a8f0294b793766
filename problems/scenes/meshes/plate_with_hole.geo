// The plate of plate_with_hole.msh as a gmsh geometry: [0, 2] x [0, 1] with a hole of radius
// 0.25 about (1, 0.5). With `geometry = { geo = "meshes/plate_with_hole.geo", body = "plate" }`
// mixvi meshes it with gmsh (optional) and refines with gmsh, so new nodes of the hole lie on
// the circle at every level (docs/design.md, "Meshes from files").
SetFactory("Built-in");
h = 0.2;
Point(1) = {0, 0, 0, h};
Point(2) = {2, 0, 0, h};
Point(3) = {2, 1, 0, h};
Point(4) = {0, 1, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Point(5) = {1, 0.5, 0, h};
Point(6) = {1.25, 0.5, 0, h / 2};
Point(7) = {1, 0.75, 0, h / 2};
Point(8) = {0.75, 0.5, 0, h / 2};
Point(9) = {1, 0.25, 0, h / 2};
Circle(5) = {6, 5, 7};
Circle(6) = {7, 5, 8};
Circle(7) = {8, 5, 9};
Circle(8) = {9, 5, 6};
Curve Loop(1) = {1, 2, 3, 4};
Curve Loop(2) = {5, 6, 7, 8};
Plane Surface(1) = {1, 2};
Physical Surface("plate") = {1};
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Curve("hole") = {5, 6, 7, 8};
Mesh.RecombineAll = 1;
Mesh.Algorithm = 8;
Mesh.RecombinationAlgorithm = 1;
Mesh.SubdivisionAlgorithm = 1;
