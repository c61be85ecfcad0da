"""Interop: conversions to and from meshio, trimesh and pyvista; mesh files."""
