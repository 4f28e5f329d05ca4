// The L-shaped bracket of examples/bracket.geo without its bolt hole, in metres: a base 0.1 x 0.06 x 0.01 and a
// wall 0.01 x 0.06 x 0.08 standing on its end x = 0. With no curved surface it meshes (and refines) from coarse
// sizes up: the price study's dynamic part (examples/swing.opts, docs/study.md).
// Physical groups: clamp (the back of the wall, x = 0), load (the free end of the base, x = 0.1), solid.
//   hyperelastic mesh examples/lbracket.geo --size 0.02 --refine 2 -o lbracket.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.1, 0.06, 0.01};
Box(2) = {0, 0, 0, 0.01, 0.06, 0.08};
BooleanUnion(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
e = 1e-6;
Physical Surface("clamp", 1) = Surface In BoundingBox{-e, -e, -e, e, 0.06 + e, 0.08 + e};
Physical Surface("load", 2) = Surface In BoundingBox{0.1 - e, -e, -e, 0.1 + e, 0.06 + e, 0.01 + e};
Physical Volume("solid", 3) = {3};
