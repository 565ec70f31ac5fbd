// A sphere in a box, as a CFD or FEA mesh of external flow has it (issue
// #21): eight layers of prisms grown from the sphere along its normals
// (0.096 thick, first 0.005), tetrahedra from the layer's top to the box.
// quads = 1 recombines the sphere's triangles into quads first: the layer is
// then hexahedra with some prisms, and gmsh puts pyramids between its quads
// and the tetrahedra. A node view "T" (smooth, not symmetric) is saved with
// the mesh:
//   gmsh sphere_bl.geo -parse_and_exit -setnumber h H -setnumber hfar HF
//        -setnumber quads Q -setnumber version V -setstring out NAME
// writes NAME.msh. h is the cell size on the sphere, hfar at the box's
// corners. make.sh writes the small test mesh; the benchmark meshes are
//   h 0.035 hfar 0.15 quads 0: 212,666 tets, 52,048 wedges (80% tets)
//   h 0.025 hfar 0.25 quads 1: 246,562 tets, 49,456 hexahedra, 16 wedges,
//                              6,182 pyramids (82% tets)
// (gmsh 4.8.4, MSH 4.1 binary, 15 and 18 MB; 20 s and 50 s).
DefineConstant[h = 0.04, hfar = 0.3, quads = 0, version = 4.1, binary = 1, out = "sphere_bl"];
Geometry.ExtrudeReturnLateralEntities = 0;
r = 0.5; L = 2;
Point(1) = {0, 0, 0, h};
Point(2) = {r, 0, 0, h}; Point(3) = {0, r, 0, h}; Point(4) = {-r, 0, 0, h};
Point(5) = {0, -r, 0, h}; Point(6) = {0, 0, r, h}; Point(7) = {0, 0, -r, h};
Circle(1) = {2, 1, 3}; Circle(2) = {3, 1, 4}; Circle(3) = {4, 1, 5}; Circle(4) = {5, 1, 2};
Circle(5) = {2, 1, 6}; Circle(6) = {6, 1, 4}; Circle(7) = {4, 1, 7}; Circle(8) = {7, 1, 2};
Circle(9) = {3, 1, 6}; Circle(10) = {6, 1, 5}; Circle(11) = {5, 1, 7}; Circle(12) = {7, 1, 3};
Curve Loop(1) = {1, 9, -5}; Surface(1) = {1};
Curve Loop(2) = {2, -6, -9}; Surface(2) = {2};
Curve Loop(3) = {3, -10, 6}; Surface(3) = {3};
Curve Loop(4) = {4, 5, 10}; Surface(4) = {4};
Curve Loop(5) = {-1, -8, 12}; Surface(5) = {5};
Curve Loop(6) = {-2, -12, -7}; Surface(6) = {6};
Curve Loop(7) = {-3, 7, -11}; Surface(7) = {7};
Curve Loop(8) = {-4, 11, 8}; Surface(8) = {8};
If (quads)
  Recombine Surface{1:8};
EndIf
// Along the normals (no direction given); bl[] = each patch's top surface, then its volume.
bl[] = Extrude { Surface{1:8}; Layers{ {1,1,1,1,1,1,1,1}, {0.005,0.012,0.021,0.032,0.045,0.06,0.077,0.096} }; Recombine; };
// The box around the layer, tetrahedra between the box and the layer's top.
Point(1001) = {-L, -L, -L, hfar}; Point(1002) = {L, -L, -L, hfar}; Point(1003) = {L, L, -L, hfar}; Point(1004) = {-L, L, -L, hfar};
Point(1005) = {-L, -L, L, hfar}; Point(1006) = {L, -L, L, hfar}; Point(1007) = {L, L, L, hfar}; Point(1008) = {-L, L, L, hfar};
Line(1001) = {1001, 1002}; Line(1002) = {1002, 1003}; Line(1003) = {1003, 1004}; Line(1004) = {1004, 1001};
Line(1005) = {1005, 1006}; Line(1006) = {1006, 1007}; Line(1007) = {1007, 1008}; Line(1008) = {1008, 1005};
Line(1009) = {1001, 1005}; Line(1010) = {1002, 1006}; Line(1011) = {1003, 1007}; Line(1012) = {1004, 1008};
Curve Loop(1001) = {1001, 1002, 1003, 1004}; Plane Surface(1001) = {1001};
Curve Loop(1002) = {1005, 1006, 1007, 1008}; Plane Surface(1002) = {1002};
Curve Loop(1003) = {1001, 1010, -1005, -1009}; Plane Surface(1003) = {1003};
Curve Loop(1004) = {1002, 1011, -1006, -1010}; Plane Surface(1004) = {1004};
Curve Loop(1005) = {1003, 1012, -1007, -1011}; Plane Surface(1005) = {1005};
Curve Loop(1006) = {1004, 1009, -1008, -1012}; Plane Surface(1006) = {1006};
Surface Loop(1001) = {1001:1006};
Surface Loop(1002) = {bl[{0:14:2}]};  // the layer's top
Volume(1001) = {1001, 1002};
Mesh 3;
Plugin(NewView).NumComp = 1;
Plugin(NewView).Run;
Plugin(ModifyComponents).Expression0 = "Exp(-1.5*(Sqrt(x^2+y^2+z^2)-0.5)) + 0.3*Sin(2*x)*Cos(1.5*y) + 0.2*z";
Plugin(ModifyComponents).View = 0;
Plugin(ModifyComponents).Run;
View[0].Name = "T";
Mesh.MshFileVersion = version;
Mesh.Binary = binary;
Save View[0] StrCat(out, ".msh");
