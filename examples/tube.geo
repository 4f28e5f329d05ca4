// A flattened rubber tube (a hose laid flat, a bellows' fold) squeezed between two plates until its inner walls touch
// and press: self-contact of nearly incompressible rubber (the mixed P2-P1 formulation). Half of an elliptic ring,
// outer semi-axes 1 x 0.35, inner 0.8 x 0.15, a slice 0.1 long; x = 0 is a symmetry plane.
// Physical groups: xsym (x = 0), ends (z = 0 and z = 0.1), outer, inner, solid.
//   hyperelastic mesh examples/tube.geo --size 0.1 -o tube.msh
//   hyperelastic run examples/tube.opts -mesh tube.msh
SetFactory("OpenCASCADE");
Disk(1) = {0, 0, 0, 1, 0.35};
Disk(2) = {0, 0, 0, 0.8, 0.15};
BooleanDifference{ Surface{1}; Delete; }{ Surface{2}; Delete; }
Extrude {0, 0, 0.1} { Surface{1}; }
Box(3) = {0, -1.5, -0.5, 1.5, 3, 1.1};
BooleanIntersection{ Volume{1}; Delete; }{ Volume{3}; Delete; }
e = 1e-4;      // (the booleans leave the cut faces' tolerance at 5e-6)
Physical Surface("xsym", 1) = Surface In BoundingBox{-e, -1 - e, -e, e, 1 + e, 0.1 + e};
Physical Surface("ends", 2) = Surface In BoundingBox{-e, -1 - e, -e, 1 + e, 1 + e, e};
Physical Surface("ends", 2) += Surface In BoundingBox{-e, -1 - e, 0.1 - e, 1 + e, 1 + e, 0.1 + e};
Physical Surface("inner", 3) = Surface In BoundingBox{-e, -0.15 - e, -e, 0.8 + e, 0.15 + e, 0.1 + e};
Physical Surface("outer", 4) = Surface In BoundingBox{-e, -1 - e, -e, 1 + e, 1 + e, 0.1 + e};
Physical Surface("outer", 4) -= Surface In BoundingBox{-e, -1 - e, -e, e, 1 + e, 0.1 + e};
Physical Surface("outer", 4) -= Surface In BoundingBox{-e, -1 - e, -e, 1 + e, 1 + e, e};
Physical Surface("outer", 4) -= Surface In BoundingBox{-e, -1 - e, 0.1 - e, 1 + e, 1 + e, 0.1 + e};
Physical Surface("outer", 4) -= Surface In BoundingBox{-e, -0.15 - e, -e, 0.8 + e, 0.15 + e, 0.1 + e};
Physical Volume("solid", 5) = {1};
