// The unit cube [0,1]^3 with a physical surface on each face (named after the bounding-box faces'
// opposites so that a test can tell them apart: xmin, xmax, ymin, ymax, zmin, zmax) and the volume "body".
//   hyperelastic mesh examples/cube.geo --size 0.25 -o cube.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
e = 1e-6;
Physical Surface("xmin", 1) = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
Physical Surface("xmax", 2) = Surface In BoundingBox{1 - e, -e, -e, 1 + e, 1 + e, 1 + e};
Physical Surface("ymin", 3) = Surface In BoundingBox{-e, -e, -e, 1 + e, e, 1 + e};
Physical Surface("ymax", 4) = Surface In BoundingBox{-e, 1 - e, -e, 1 + e, 1 + e, 1 + e};
Physical Surface("zmin", 5) = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
Physical Surface("zmax", 6) = Surface In BoundingBox{-e, -e, 1 - e, 1 + e, 1 + e, 1 + e};
Physical Volume("body", 7) = {1};
