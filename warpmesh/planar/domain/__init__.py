"""Triangle meshes of planar implicit domains [FG §16.5.2]: conforming Delaunay, refinement, smoothing, the Triangle cross-check."""
