"""Lazy imports of the ``harness`` extra (pandas, matplotlib, tqdm) with an install hint."""

from __future__ import annotations

import importlib
from types import ModuleType


def require(module: str) -> ModuleType:
    """Import ``module`` or raise ``ImportError`` saying how to install the extra."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise ImportError(
            f"the evaluation harness needs {module.split('.')[0]}: "
            "pip install 'o3d-spectral[harness]'"
        ) from error
