// Cantilever beam 100 x 10 x 10 mm for the FEM verification tests.
// Meshes: gmsh beam.geo -3 -clmax 5|2.5|1.25 -format msh2 -o beam_<h>.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 100, 10, 10};
