// Kidney (bean) shaped 2D cross-section for springfit examples.
// About 10 units long (x in [-5,5]) and 6 units wide (y in [-3,3]),
// with the hilum (concave indentation) on the upper long side.
// Regenerate the mesh with examples/meshes/make-kidney.sh.

If (!Exists(lc))
  lc = 0.9;   // characteristic length (override with: gmsh -setnumber lc X)
EndIf

// Closed Catmull-Rom spline through control points, counter-clockwise.
Point(1)  = { 5.0,  0.2, 0, lc};
Point(2)  = { 4.5,  1.9, 0, lc};
Point(3)  = { 3.2,  2.9, 0, lc};
Point(4)  = { 1.6,  2.9, 0, lc};
Point(5)  = { 0.6,  2.0, 0, lc};
Point(6)  = { 0.0,  1.7, 0, lc};   // hilum
Point(7)  = {-0.6,  2.0, 0, lc};
Point(8)  = {-1.6,  2.9, 0, lc};
Point(9)  = {-3.2,  2.9, 0, lc};
Point(10) = {-4.5,  1.9, 0, lc};
Point(11) = {-5.0,  0.2, 0, lc};
Point(12) = {-4.4, -1.7, 0, lc};
Point(13) = {-2.8, -2.8, 0, lc};
Point(14) = {-0.9, -3.05, 0, lc};
Point(15) = { 0.9, -3.05, 0, lc};
Point(16) = { 2.8, -2.8, 0, lc};
Point(17) = { 4.4, -1.7, 0, lc};

Spline(1) = {1:17, 1};
Curve Loop(1) = {1};
Plane Surface(1) = {1};
Physical Curve("boundary", 1) = {1};
Physical Surface("kidney", 1) = {1};

// Fixed, deterministic meshing options.
Mesh.Algorithm = 6;            // Frontal-Delaunay
Mesh.RandomFactor = 1e-9;
Mesh.RandomSeed = 1;
Mesh.ElementOrder = 1;
Mesh.Smoothing = 10;
Mesh.RecombineAll = 0;
Mesh.MeshSizeFromPoints = 1;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeExtendFromBoundary = 1;
Mesh.MeshSizeMin = lc;
Mesh.MeshSizeMax = lc;
Mesh.MshFileVersion = 2.2;
Mesh.Binary = 0;
Mesh.SaveAll = 0;
