"""Implicit curves and planar domains [FG §16.1-16.3, §16.5.2]: mesh_curve, mesh_domain, the curve samplers, geometric curve meshes."""
