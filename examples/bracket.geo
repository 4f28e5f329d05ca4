// An L-shaped bracket, in metres: a base 0.1 x 0.06 x 0.01 with a bolt hole (radius 0.01), and a wall
// 0.01 x 0.06 x 0.08 standing on its end x = 0.
// Physical groups: clamp (the back of the wall, x = 0), load (the free end of the base, x = 0.1),
// solid (the volume).
//   hyperelastic mesh examples/bracket.geo --size 0.006 -o bracket.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.1, 0.06, 0.01};
Box(2) = {0, 0, 0, 0.01, 0.06, 0.08};
BooleanUnion(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Cylinder(4) = {0.06, 0.03, -0.001, 0, 0, 0.012, 0.01};
BooleanDifference(5) = { Volume{3}; Delete; }{ Volume{4}; Delete; };
e = 1e-6;
Physical Surface("clamp", 1) = Surface In BoundingBox{-e, -e, -e, e, 0.06 + e, 0.08 + e};
Physical Surface("load", 2) = Surface In BoundingBox{0.1 - e, -e, -e, 0.1 + e, 0.06 + e, 0.01 + e};
Physical Volume("solid", 3) = {5};
