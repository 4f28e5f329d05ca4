// The thesis' 10 x 4 x 4 bar meshed with sliver tetrahedra: a transfinite (structured) grid of
// 400 x 2 x 2 boxes of 0.025 x 2 x 2, each split into tetrahedra, so the longest edge is about 113
// times the shortest altitude. The level/size given to `hyperelastic mesh` does not change it.
SetFactory("OpenCASCADE");
Box(1) = {-5, -2, -2, 10, 4, 4};
Physical Volume("bar", 1) = {1};
ex[] = Curve{:};
For i In {0 : #ex[] - 1}
  b[] = BoundingBox Curve{ex[i]};
  If (b[3] - b[0] > 5)
    Transfinite Curve{ex[i]} = 401;
  Else
    Transfinite Curve{ex[i]} = 3;
  EndIf
EndFor
Transfinite Surface{:};
Transfinite Volume{1};
