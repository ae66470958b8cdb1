// A 40 x 20 mm tissue sample, 1 mm thick, with a stiffer 10 x 6 mm inclusion: the mesh of the
// README's pipeline (gmsh -> springfit import -> run -> export). Its sides and both regions
// are named physical groups: the loads file (inclusion-loads.json) refers to them.
lc = 2.5;
Point(1) = {0, 0, 0, lc};   Point(2) = {40, 0, 0, lc};
Point(3) = {40, 20, 0, lc}; Point(4) = {0, 20, 0, lc};
Point(5) = {15, 7, 0, lc};  Point(6) = {25, 7, 0, lc};
Point(7) = {25, 13, 0, lc}; Point(8) = {15, 13, 0, lc};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Line(5) = {5, 6}; Line(6) = {6, 7}; Line(7) = {7, 8}; Line(8) = {8, 5};
Curve Loop(1) = {1, 2, 3, 4};
Curve Loop(2) = {5, 6, 7, 8};
Plane Surface(1) = {1, 2};
Plane Surface(2) = {2};
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("tissue") = {1};
Physical Surface("inclusion") = {2};
