"""Lazy public names of a package: a submodule is imported when one of its names is first used.

``import lsadphoto`` or ``from lsadphoto.io import read_map`` should not import the RAW
decoder, OpenCV, SciPy or matplotlib: a ``lsadphoto score`` process would pay for them on
every run. Each package ``__init__`` therefore lists its public names by submodule and hands
the list to :func:`lazy_exports`, which returns the module-level ``__getattr__`` and
``__dir__`` of PEP 562 and the ``__all__`` list. A name is imported on first access (also by
``from package import name`` and ``import *``) and then stored in the package's namespace, so
later accesses cost nothing.

References
----------
PEP 562 — Module ``__getattr__`` and ``__dir__`` (Python 3.7).
"""

import importlib

__all__ = ["lazy_exports"]


def lazy_exports(package, namespace, exports):
    """``(__getattr__, __dir__, __all__)`` for ``package`` exporting ``exports``.

    ``package`` is the package's ``__name__``, ``namespace`` its ``globals()``, ``exports`` a
    mapping from a relative submodule name (``".hdr"``) to the public names it defines.

    Examples
    --------
    >>> getattr_, dir_, names = lazy_exports("lsadphoto", {}, {".errors": ["BadInputError"]})
    >>> names, getattr_("BadInputError").__name__
    (['BadInputError'], 'BadInputError')
    """
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        namespace[name] = value
        return value

    def __dir__():
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__, list(where)
