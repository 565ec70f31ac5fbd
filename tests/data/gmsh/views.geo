// layer.geo's prisms with two model-based views, for the binary tests:
// "T" = x + 10y + 100z at the nodes ($NodeData) and gmsh's Jacobian
// quality per element ($ElementData, "q"). make.sh runs it once per
// format: gmsh views.geo -parse_and_exit -setnumber version 4.1
// -setnumber binary 1 -setstring out NAME writes NAME_T.msh and NAME_q.msh
// (each view with the mesh), which it then joins.
DefineConstant[version = 4.1, binary = 0, out = "views"];
Merge "layer.geo";
Mesh 3;
Plugin(NewView).NumComp = 1;
Plugin(NewView).Run;
Plugin(ModifyComponents).Expression0 = "x + 10*y + 100*z";
Plugin(ModifyComponents).View = 0;
Plugin(ModifyComponents).Run;
View[0].Name = "T";
Plugin(AnalyseMeshQuality).JacobianDeterminant = 1;
Plugin(AnalyseMeshQuality).CreateView = 1;
Plugin(AnalyseMeshQuality).DimensionOfElements = 3;
Plugin(AnalyseMeshQuality).Run;
View[1].Name = "q";
Mesh.MshFileVersion = version;
Mesh.Binary = binary;
Save View[0] StrCat(out, "_T.msh");
Save View[1] StrCat(out, "_q.msh");
