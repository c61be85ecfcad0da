"""Bricked meshing on a Dask cluster: ``mesh_surface(source, ..., client=client)``.

The grid is cut into bricks on block boundaries (:mod:`~warpmesh.distributed.bricks`);
each brick is meshed by a worker with the kernels of one process on the global grid and
its seam vertices keyed by their global grid-edge ids (:mod:`~warpmesh.distributed.run`),
so the seams weld exactly (:mod:`~warpmesh.distributed.seams`) and the mesh is the one a
single process makes; pieces stream to VTU files and a ``.pvtu``
(:mod:`~warpmesh.distributed.output`). Needs the ``distributed`` extra
(``pip install warpmesh[distributed]``); importing this package does not import Dask.
"""
