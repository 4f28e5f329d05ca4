// Two unit cubes of one mesh, one above the other with a gap of 0.05 (separate pieces: self-contact's test and
// example). Physical groups: base (z = 0), lid (z = 2.05), xsym (x = 0), ysym (y = 0), facing (the two faces across
// the gap), lower and upper (the volumes).
//   hyperelastic mesh examples/stack.geo --size 0.25 -o stack.msh
//   hyperelastic run examples/stack.opts -mesh stack.msh
SetFactory("OpenCASCADE");
g = 0.05;
Box(1) = {0, 0, 0, 1, 1, 1};
Box(2) = {0, 0, 1 + g, 1, 1, 1};
e = 1e-6;
Physical Surface("base", 1) = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Surface("lid", 2) = Surface In BoundingBox{-e, -e, 2 + g - e, 1 + e, 1 + e, 2 + g + e};
Physical Surface("xsym", 3) = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 2 + g + e};
Physical Surface("ysym", 4) = Surface In BoundingBox{-e, -e, -e, 1 + e, e, 2 + g + e};
Physical Surface("facing", 5) = Surface In BoundingBox{-e, -e, 1 - e, 1 + e, 1 + e, 1 + g + e};
Physical Volume("lower", 6) = {1};
Physical Volume("upper", 7) = {2};
