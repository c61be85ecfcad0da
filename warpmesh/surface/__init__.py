"""Surface meshes of shapes and sampled volumes [FG §16.4]: the public mesh_surface, the block grid, continuation covering, volumes, the adaptive octree, orientation."""
