"""The curve samplers of [FG §16.3.1]: grid (marching squares), progression, continuation, quadtree, rays; automatic seeds."""
