// A slender rod for the coil example (examples/coil.opts): radius 0.05, length 2 (aspect 20), on the x axis from
// x = 0 to x = 2. Physical groups: left (x = 0), right (x = 2), side (r = 0.05), rod (the volume).
//   hyperelastic mesh examples/coil.geo --size 0.03 -o coil.msh
//   hyperelastic run examples/coil.opts -mesh coil.msh
SetFactory("OpenCASCADE");
a = 0.05; L = 2;
Cylinder(1) = {0, 0, 0, L, 0, 0, a};
e = 1e-6;
Physical Surface("left", 1) = Surface In BoundingBox{-e, -a - e, -a - e, e, a + e, a + e};
Physical Surface("right", 2) = Surface In BoundingBox{L - e, -a - e, -a - e, L + e, a + e, a + e};
Physical Surface("side", 3) = Surface In BoundingBox{e, -a - e, -a - e, L - e, a + e, a + e};
Physical Volume("rod", 4) = {1};
