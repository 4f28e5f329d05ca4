// A quarter of a thick-walled cylinder (Lame's problem), in metres: inner radius 0.1, outer radius 0.2,
// 0.05 long, the quarter x >= 0, y >= 0. Physical groups: inner (r = 0.1), outer (r = 0.2), xsym (x = 0),
// ysym (y = 0), bottom (z = 0), top (z = 0.05), solid. Plane strain with rollers on both ends:
//   -fix xsym:x,ysym:y,bottom:z,top:z -pressure P -pressure_faces inner
// Lame (plane strain, linear): u_r(r) = (1 + nu) P a^2 / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r).
//   hyperelastic mesh examples/cylinder.geo --size 0.02 --order 2 -o cylinder.msh
SetFactory("OpenCASCADE");
a = 0.1; b = 0.2; L = 0.05;
Cylinder(1) = {0, 0, 0, 0, 0, L, b, Pi / 2};
Cylinder(2) = {0, 0, -1, 0, 0, L + 2, a, Pi / 2};
BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }
e = 1e-6;
si() = Surface In BoundingBox{-e, -e, -e, a + e, a + e, L + e};
sx() = Surface In BoundingBox{-e, -e, -e, e, b + e, L + e};
sy() = Surface In BoundingBox{-e, -e, -e, b + e, e, L + e};
sb() = Surface In BoundingBox{-e, -e, -e, b + e, b + e, e};
st() = Surface In BoundingBox{-e, -e, L - e, b + e, b + e, L + e};
so() = Surface "*";
so() -= {si(), sx(), sy(), sb(), st()};
Physical Surface("inner", 1) = {si()};
Physical Surface("outer", 2) = {so()};
Physical Surface("xsym", 3) = {sx()};
Physical Surface("ysym", 4) = {sy()};
Physical Surface("bottom", 5) = {sb()};
Physical Surface("top", 6) = {st()};
Physical Volume("solid", 7) = {1};
