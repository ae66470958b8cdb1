// A 4 x 2 x 2 block of tetrahedra for the probe fit at organ size (bench/RESULTS.md, "Fitting
// the response"): the mesh size comes from the command line, gmsh -3 -clmin H -clmax H
// (H 0.155: 4,346 nodes; H 0.1135: 10,582 nodes, with gmsh 4.11 of Debian 12).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 4, 2, 2};
Physical Surface("fixed") = {1};
Physical Surface("pulled") = {2};
Physical Surface("top") = {6};
Physical Volume("body") = {1};
