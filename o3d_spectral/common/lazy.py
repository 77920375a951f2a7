"""Package attributes imported on first access (PEP 562), so that importing one module of
a package does not import all the others (and the packages may use each other's modules
without an import cycle through their ``__init__``)."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Iterable
from typing import Any


def lazy_attributes(package: str, where: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that imports ``name`` from the submodule
    ``where[name]`` on first access (a name starting with a dot is relative to ``package``,
    as in a relative import: ``"..synthetic.symmetry"``)."""

    def __getattr__(name: str) -> Any:
        if name not in where:
            # A submodule not imported yet (``import pkg; pkg.sub``), as an eager package
            # that had imported it would have it.
            if importlib.util.find_spec(f"{package}.{name}") is not None:
                return importlib.import_module(f"{package}.{name}")
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = where[name]
        if module.startswith("."):
            return getattr(importlib.import_module(module, package), name)
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return __getattr__


def lazy_dir(namespace: dict[str, Any], names: Iterable[str]) -> Callable[[], list[str]]:
    """A module ``__dir__`` listing the module's own ``namespace`` (its ``globals()``) and
    the ``names`` it loads lazily (its ``__all__``), for ``dir()``, ``help()`` and tab
    completion, which look only at what is already imported otherwise."""
    names = frozenset(names)
    return lambda: sorted(names.union(namespace))
