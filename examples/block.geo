// A block under partial compression (the geometry of deal.II's step-44, with z vertical), in mm: the unit cube,
// a quarter of it by symmetry, loaded on the patch [0,0.5] x [0,0.5] of its top face. Physical groups: patch
// (the loaded part of the top), top (the rest of it), xsym (x = 0), ysym (y = 0), bottom (z = 0), solid.
//   hyperelastic mesh examples/block.geo --size 0.125 --order 2 -o block.msh
//   hyperelastic run examples/block.opts -mesh block.msh -formulation mixed
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Rectangle(10) = {0, 0, 1, 0.5, 0.5};
BooleanFragments{ Volume{1}; Delete; }{ Surface{10}; Delete; }
e = 1e-6;
sp() = Surface In BoundingBox{-e, -e, 1 - e, 0.5 + e, 0.5 + e, 1 + e};
st() = Surface In BoundingBox{-e, -e, 1 - e, 1 + e, 1 + e, 1 + e};
st() -= {sp()};
Physical Surface("patch", 1) = {sp()};
Physical Surface("top", 2) = {st()};
Physical Surface("xsym", 3) = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
Physical Surface("ysym", 4) = Surface In BoundingBox{-e, -e, -e, 1 + e, e, 1 + e};
Physical Surface("bottom", 5) = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Volume("solid", 6) = Volume{:};
