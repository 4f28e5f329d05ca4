// A bar of two materials joined at x = 1: [0,1]x[0,0.25]^2 is the physical volume "soft",
// [1,2]x[0,0.25]^2 the physical volume "stiff"; the two share the interface's mesh (fragments).
//   hyperelastic mesh examples/bimaterial.geo --size 0.125 -o bimaterial.msh
//   hyperelastic run examples/bimaterial.opts -mesh bimaterial.msh -output bimaterial.h5
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 0.25, 0.25};
Box(2) = {1, 0, 0, 1, 0.25, 0.25};
v() = BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; };
e = 1e-6;
Physical Volume("soft", 1) = Volume In BoundingBox{-e, -e, -e, 1 + e, 0.25 + e, 0.25 + e};
Physical Volume("stiff", 2) = Volume In BoundingBox{1 - e, -e, -e, 2 + e, 0.25 + e, 0.25 + e};
Physical Surface("end_soft", 3) = Surface In BoundingBox{-e, -e, -e, e, 0.25 + e, 0.25 + e};
Physical Surface("end_stiff", 4) = Surface In BoundingBox{2 - e, -e, -e, 2 + e, 0.25 + e, 0.25 + e};
