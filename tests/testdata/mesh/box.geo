// 4 x 2 x 1 mm box with named regions (surface 5 is in two groups). Regenerate with
//   gmsh -3 -format msh22 box.geo -o box_msh22.msh   (likewise msh41, msh41 -bin, vtk, stl)
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 4, 2, 1};
Physical Volume("tendon", 7) = {1};
Physical Surface("footprint", 3) = {5};
Physical Surface("skin", 4) = {1, 2, 3, 4, 5, 6};
Physical Curve("edge", 11) = {1};
MeshSize{ PointsOf{ Volume{1}; } } = 0.5;
