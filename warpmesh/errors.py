"""The warpmesh exception family.

Bad arguments raise the built-in ``ValueError`` / ``TypeError`` ("expected X, got Y");
failures of an algorithm or of a file raise a :class:`WarpMeshError` subclass, so a
caller can catch everything warpmesh-specific with one ``except WarpMeshError``.

Examples
--------
>>> from warpmesh.errors import ReadError, WarpMeshError
>>> issubclass(ReadError, WarpMeshError) and issubclass(ReadError, ValueError)
True
"""

from __future__ import annotations

__all__ = ["WarpMeshError", "ReadError", "WriteError", "TopologyError", "MergeError", "SizeError"]


class WarpMeshError(Exception):
    """Base class of every warpmesh-specific failure."""


class ReadError(WarpMeshError, ValueError):
    """A mesh file exists but cannot be parsed; the message names the path and format."""


class WriteError(WarpMeshError, ValueError):
    """A mesh file writer (meshio's) failed on a mesh; the message names the path and
    format, and nothing is left on disk."""


class TopologyError(WarpMeshError):
    """A mesh does not have the topology an operation needs (e.g. it is not manifold)."""


class MergeError(WarpMeshError):
    """The merged mesh fails the Euler check: the interfaces do not match."""


class SizeError(WarpMeshError, ValueError):
    """An argument asks for more memory than the budget (:mod:`warpmesh._util.budget`);
    raised before any work, with the size it would need and the argument to change."""
