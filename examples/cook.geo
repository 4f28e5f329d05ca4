// Cook's membrane (Cook 1974; nearly incompressible in Simo & Rifai 1990, Auricchio et al. 2005), in mm:
// the tapered panel (0,0), (48,44), (48,60), (0,44), 10 thick. Physical groups: left (x = 0, clamped),
// right (x = 48, the shear load), front (z = 0), back (z = 10) for plane strain by rollers, solid.
//   hyperelastic mesh examples/cook.geo --size 2 --order 2 -o cook.msh
SetFactory("OpenCASCADE");
Point(1) = {0, 0, 0};
Point(2) = {48, 44, 0};
Point(3) = {48, 60, 0};
Point(4) = {0, 44, 0};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Extrude {0, 0, 10} { Surface{1}; }
e = 1e-6;
Physical Surface("left", 1) = Surface In BoundingBox{-e, -e, -e, e, 60 + e, 10 + e};
Physical Surface("right", 2) = Surface In BoundingBox{48 - e, -e, -e, 48 + e, 60 + e, 10 + e};
Physical Surface("front", 3) = Surface In BoundingBox{-e, -e, -e, 48 + e, 60 + e, e};
Physical Surface("back", 4) = Surface In BoundingBox{-e, -e, 10 - e, 48 + e, 60 + e, 10 + e};
Physical Volume("solid", 5) = {1};
