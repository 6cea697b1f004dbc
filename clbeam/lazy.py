"""Package attributes imported on first use (PEP 562).

A package's ``__init__`` lists what it offers; importing the package (or
any module inside it) then costs nothing until one of those names is used.
The command line starts in a fraction of a second this way although its
packages reach xarray, SciPy and the OpenCL engine.
"""

from __future__ import annotations

import importlib
import sys


def lazy_exports(package: str, exports: dict[str, tuple[str, ...]]):
    """``__getattr__`` and ``__dir__`` for ``package`` whose names come from the given modules.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : dict
        Module name -> the names the package takes from it.

    Returns
    -------
    (callable, callable)
        The module-level ``__getattr__`` and ``__dir__``.
    """
    origin = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        module = origin.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)  # later lookups skip this function
        return value

    def __dir__():
        return sorted(set(origin) | set(vars(sys.modules[package])))

    return __getattr__, __dir__
