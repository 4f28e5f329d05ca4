// The 10 x 4 x 4 bar of the thesis' framework, centred at the origin: [-5,5] x [-2,2] x [-2,2].
// The target edge length is set from the command line / API (Mesh.MeshSizeMin/Max), see
// `hyperelastic mesh bar --level N`.
SetFactory("OpenCASCADE");
Box(1) = {-5, -2, -2, 10, 4, 4};
Physical Volume("bar", 1) = {1};
