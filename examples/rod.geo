// A rubber rod for torsion, in metres: radius a = 0.01, length L = 0.04, on the z axis from z = 0 to z = L.
// Physical groups: bottom (z = 0), top (z = L), side (r = a), rod (the volume).
//   hyperelastic mesh examples/rod.geo --size 0.005 --order 2 -o rod.msh
SetFactory("OpenCASCADE");
a = 0.01; L = 0.04;
Cylinder(1) = {0, 0, 0, 0, 0, L, a};
e = 1e-6;
Physical Surface("bottom", 1) = Surface In BoundingBox{-a - e, -a - e, -e, a + e, a + e, e};
Physical Surface("top", 2) = Surface In BoundingBox{-a - e, -a - e, L - e, a + e, a + e, L + e};
Physical Surface("side", 3) = Surface In BoundingBox{-a - e, -a - e, e, a + e, a + e, L - e};
Physical Volume("rod", 4) = {1};
