"""Mesh modifications [FG ch. 17]: transforms, uniform and local refinement, cell-type conversion, hexahedron splits, merge, periodic meshes, cracks."""
