"""Tetrahedral meshes of implicit domains: isosurface stuffing on a body-centred cubic lattice
in Warp kernels (stencil tables generated in code, dihedral angles bounded), boundary refs,
quality (dihedral angles, radius-edge ratio) and quality-safe smoothing."""
