// Hertz contact (issue 46's verification): a quarter of the lower half of a ball of radius 1 (centre (0,0,1), the pole
// at the origin), graded toward the pole (edges HMIN there, 0.2 beyond 0.7 from it: a Distance + Threshold field;
// keep it with --graded). Physical groups: top (the flat face z = 1), xsym (x = 0), ysym (y = 0), ball (the curved
// surface), solid.
//   hyperelastic mesh examples/hertz.geo --size 0.2 --graded -o hertz.msh
//   hyperelastic run examples/hertz.opts -mesh hertz.msh
SetFactory("OpenCASCADE");
If (!Exists(HMIN))
  HMIN = 0.02;
EndIf
Sphere(1) = {0, 0, 1, 1, -Pi/2, 0, Pi/2};
e = 1e-6;
Physical Surface("top", 1) = Surface In BoundingBox{-e, -e, 1 - e, 1 + e, 1 + e, 1 + e};
Physical Surface("xsym", 2) = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e};
Physical Surface("ysym", 3) = Surface In BoundingBox{-e, -e, -e, 1 + e, e, 1 + e};
all() = Surface{:};
Physical Surface("ball", 4) = {all()};
Physical Surface("ball", 4) -= {Surface In BoundingBox{-e, -e, 1 - e, 1 + e, 1 + e, 1 + e}};
Physical Surface("ball", 4) -= {Surface In BoundingBox{-e, -e, -e, e, 1 + e, 1 + e}};
Physical Surface("ball", 4) -= {Surface In BoundingBox{-e, -e, -e, 1 + e, e, 1 + e}};
Physical Volume("solid", 5) = {1};
Point(100) = {0, 0, 0};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = HMIN;
Field[2].SizeMax = 0.2;
Field[2].DistMin = 0.15;
Field[2].DistMax = 0.7;
Background Field = 2;
