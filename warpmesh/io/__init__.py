"""Interop: conversions to and from meshio, trimesh and pyvista; mesh files; image volumes in
(VTK, NIfTI, NRRD, MetaImage, DICOM, numpy: :mod:`warpmesh.io.images`)."""
