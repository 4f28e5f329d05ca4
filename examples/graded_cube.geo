// A unit cube whose mesh is graded toward its corner at the origin (a contact point, a notch): edges 0.04 there,
// 0.3 beyond 0.6 from it (a gmsh Distance + Threshold background field). Keep the grading with --graded:
//   hyperelastic mesh examples/graded_cube.geo --size 0.3 --graded -o graded.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Physical Volume("cube", 1) = {1};
Field[1] = Distance;
Field[1].PointsList = {1};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = 0.04;
Field[2].SizeMax = 0.3;
Field[2].DistMin = 0.05;
Field[2].DistMax = 0.6;
Background Field = 2;
