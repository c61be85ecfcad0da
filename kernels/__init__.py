"""Device code of warpmesh: every ``@wp.kernel`` / ``@wp.func`` and the tables they read.

Installed as the subpackage ``warpmesh.kernels``. Nothing here imports host
orchestration; the host partners in ``warpmesh/`` validate, allocate and launch.
"""
