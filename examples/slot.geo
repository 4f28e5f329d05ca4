// A block with a slot (self-contact's example of one body closing on itself): 4 x 1 x 2 with a slot 0.1 high cut
// from its end x = 4 back to x = 1 at mid-height, so that an upper and a lower arm face each other across it.
// Physical groups: base (z = 0), top (z = 2), back (x = 0), ysym (y = 0), slot (the slot's faces), solid.
//   hyperelastic mesh examples/slot.geo --size 0.2 -o slot.msh
//   hyperelastic run examples/slot.opts -mesh slot.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 4, 1, 2};
Box(2) = {1, -0.5, 0.95, 3.5, 2, 0.1};
BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }
e = 1e-6;
Physical Surface("base", 1) = Surface In BoundingBox{-e, -e, -e, 4 + e, 1 + e, e};
Physical Surface("top", 2) = Surface In BoundingBox{-e, -e, 2 - e, 4 + e, 1 + e, 2 + e};
Physical Surface("back", 3) = Surface In BoundingBox{-e, -e, -e, e, 1 + e, 2 + e};
Physical Surface("ysym", 4) = Surface In BoundingBox{-e, -e, -e, 4 + e, e, 2 + e};
Physical Surface("slot", 5) = Surface In BoundingBox{1 - e, -e, 0.95 - e, 4 + e, 1 + e, 1.05 + e};
Physical Volume("solid", 6) = {1};
