"""A griffe extension for the API reference: docstrings completed at import time.

``registration_spectral`` and ``registration_spectral_global`` share their common
parameters' description, written once and put in place of ``{common}`` when the module is
imported. Read statically, the placeholder is all griffe sees; this extension gives it the
docstring the imported function has, as ``help()`` shows it.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

import griffe

PLACEHOLDER = "{common}"


class RuntimeDocstrings(griffe.Extension):
    """Replace a docstring holding :data:`PLACEHOLDER` by the imported object's."""

    def on_function_instance(self, *, func: griffe.Function, **kwargs: Any) -> None:
        if func.docstring is None or PLACEHOLDER not in func.docstring.value:
            return
        module = importlib.import_module(func.module.path)
        func.docstring.value = inspect.cleandoc(getattr(module, func.name).__doc__)
