// A quarter of an O-ring's cross-section (cord diameter 3.53 mm, a standard AS568 size), in metres: the quadrant
// x, y >= 0 of the cord's circle, extruded 0.2 mm in z (a slice held in z: plane strain). Its symmetry planes x = 0
// and y = 0, the slice's faces front (z = 0) and back (z = 0.2 mm), and the cord's curved surface.
//   hyperelastic mesh examples/oring.geo --size 0.0003 --order 2 -o oring.msh
//   hyperelastic run examples/oring.opts -mesh oring.msh
SetFactory("OpenCASCADE");
r = 3.53e-3 / 2;
t = 0.2e-3;
Cylinder(1) = {0, 0, 0, 0, 0, t, r};
Box(2) = {0, 0, 0, 2 * r, 2 * r, t};
BooleanIntersection(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
e = 1e-3 * r;
xs() = Surface In BoundingBox{-e, -e, -e, e, r + e, t + e};
ys() = Surface In BoundingBox{-e, -e, -e, r + e, e, t + e};
fr() = Surface In BoundingBox{-e, -e, -e, r + e, r + e, e};
bk() = Surface In BoundingBox{-e, -e, t - e, r + e, r + e, t + e};
cord() = Abs(Boundary{ Volume{3}; });
cord() -= {xs(), ys(), fr(), bk()};
Physical Surface("xsym", 1) = xs();
Physical Surface("ysym", 2) = ys();
Physical Surface("front", 3) = fr();
Physical Surface("back", 4) = bk();
Physical Surface("cord", 5) = cord();
Physical Volume("rubber", 6) = {3};
