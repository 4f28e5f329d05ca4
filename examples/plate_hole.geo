// A 1 cm thick plate with a hole, in metres: 0.2 x 0.1 x 0.01 with a hole of radius 0.02 at its centre.
// Physical groups: clamp (the face x = 0), load (the face x = 0.2), solid (the volume).
//   hyperelastic mesh examples/plate_hole.geo --size 0.005 -o plate.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.2, 0.1, 0.01};
Cylinder(2) = {0.1, 0.05, -0.001, 0, 0, 0.012, 0.02};
BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }
e = 1e-6;
Physical Surface("clamp", 1) = Surface In BoundingBox{-e, -e, -e, e, 0.1 + e, 0.01 + e};
Physical Surface("load", 2) = Surface In BoundingBox{0.2 - e, -e, -e, 0.2 + e, 0.1 + e, 0.01 + e};
Physical Volume("solid", 3) = {1};
