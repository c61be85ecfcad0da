"""Surface optimisation and simplification on the exact surface [FG §16.4.3]: remeshing, local operators, features, size fields.

``wm.optimize`` is the function :func:`warpmesh.optimize.remesh.optimize`, not this package
(the package ``warpmesh`` keeps the function under that name). ``import
warpmesh.optimize.label_smoothing as ls`` looks the submodule up as an attribute of
``warpmesh.optimize``, that is of the function; so each submodule, as it is imported, is also
set on the function (this package's module class does it), and the import works in any order.

>>> import warpmesh.optimize.label_smoothing as ls
>>> ls.smooth_labels.__module__
'warpmesh.optimize.label_smoothing'
"""

import sys as _sys
from types import ModuleType as _ModuleType


class _Package(_ModuleType):
    """This package, which mirrors its submodule attributes onto the function ``optimize``."""

    def __setattr__(self, name: str, value) -> None:
        super().__setattr__(name, value)
        if isinstance(value, _ModuleType) and value.__name__ == f"{self.__name__}.{name}":
            _mirror(self)


def _mirror(package) -> None:
    """Set every submodule attribute of ``package`` on the function ``optimize`` (once it exists)."""
    function = getattr(_sys.modules.get(f"{package.__name__}.remesh"), "optimize", None)
    if function is None:
        return
    for name, value in list(vars(package).items()):
        if isinstance(value, _ModuleType) and value.__name__ == f"{package.__name__}.{name}":
            setattr(function, name, value)


_sys.modules[__name__].__class__ = _Package
