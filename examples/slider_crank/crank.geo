// Crank of examples/slider_crank: a steel bar 0.25 x 0.04 x 0.03 m along x, the shaft on the end
// face x = 0 and the crank pin on the end face x = 0.25 (node sets for the RBE2 interfaces).
SetFactory("OpenCASCADE");
Box(1) = {0, -0.02, -0.015, 0.25, 0.04, 0.03};
Physical Surface("shaft") = {1};
Physical Surface("pin") = {2};
Physical Volume("crank") = {1};
