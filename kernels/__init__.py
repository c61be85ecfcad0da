"""Device code of warpmesh: every ``@wp.kernel`` / ``@wp.func`` and the tables they read.

Installed as the subpackage ``warpmesh.kernels``. Nothing here imports host
orchestration; the host partners in ``warpmesh/`` validate, allocate and launch.

Importing this package starts Warp for warpmesh (:mod:`warpmesh.kernels.startup`: log
level, no CUDA-driver warning, the one-line notice while kernels compile). Every host
module that launches a kernel imports it from here, so Warp is started once, before the
first launch, and never by ``import warpmesh`` itself.
"""

from warpmesh.kernels.startup import start as _start

_start()
