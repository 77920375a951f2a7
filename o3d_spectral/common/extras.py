"""The optional extras (``pip install 'o3d-spectral[EXTRA]'``): which modules each brings,
and one error, :class:`MissingExtraError`, that names the extra a missing module needs.

The core install registers clouds and runs the demo; the extras add the evaluation
harness (``harness``), the servoing simulation (``servo``), Dask clusters (``cluster``),
the peer methods (``peers``) and the search's correlations on a GPU (``gpu``: CuPy). A
command that needs an extra checks for it before it starts, with :func:`require_modules`,
and the command line prints the error on one line.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

__all__ = ["EXTRAS", "MissingExtraError", "extra_of", "missing_extra", "require",
           "require_modules"]

#: The top-level modules the package imports from each extra (Pillow comes with matplotlib).
EXTRAS: dict[str, tuple[str, ...]] = {
    "harness": ("pandas", "matplotlib", "PIL", "tqdm", "orjson"),
    "servo": ("pybullet", "pybullet_data"),
    "cluster": ("dask", "distributed"),
    "peers": ("kiss_matcher", "small_gicp"),
    "gpu": ("cupy", "cupyx"),
}


class MissingExtraError(ImportError):
    """An optional module is not installed; the message names the extra that installs it:
    ``WHAT needs the 'EXTRA' extra (MODULE is missing): pip install 'o3d-spectral[EXTRA]'``.

    Attributes
    ----------
    extra : str
        The extra to install.
    """

    def __init__(self, what: str, extra: str, module: str) -> None:
        super().__init__(
            f"{what} needs the '{extra}' extra ({module} is missing): "
            f"pip install 'o3d-spectral[{extra}]'",
            name=module,
        )
        self.extra = extra


def extra_of(module: str) -> str | None:
    """The extra that installs ``module`` (a dotted name is looked up by its top level),
    None for a module of no extra."""
    top = module.partition(".")[0]
    return next((extra for extra, modules in EXTRAS.items() if top in modules), None)


def require(module: str, what: str) -> ModuleType:
    """Import ``module``.

    Parameters
    ----------
    module : str
        Dotted module name, from one of :data:`EXTRAS`.
    what : str
        What needs it, the start of the error message (e.g. ``"plots"``).

    Returns
    -------
    types.ModuleType

    Raises
    ------
    MissingExtraError
        If the module (or one it imports from an extra) cannot be imported.
    """
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise missing_extra(error, what) or MissingExtraError(
            what, extra_of(module) or "harness", module.partition(".")[0]
        ) from error


def require_modules(what: str, *modules: str) -> None:
    """Check that ``modules`` are installed, without importing them (so that a command
    fails before it starts rather than at its end).

    Raises
    ------
    MissingExtraError
        For the first module that is not installed.
    """
    for module in modules:
        if importlib.util.find_spec(module.partition(".")[0]) is None:
            raise MissingExtraError(what, extra_of(module) or "harness", module)


def missing_extra(error: BaseException, what: str) -> MissingExtraError | None:
    """``error`` as a :class:`MissingExtraError` when it is an ``ImportError`` of a module
    of one of :data:`EXTRAS` (``error`` itself if it is one already), else None."""
    if isinstance(error, MissingExtraError):
        return error
    if not isinstance(error, ImportError) or not error.name:
        return None
    extra = extra_of(error.name)
    return None if extra is None else MissingExtraError(what, extra, error.name.partition(".")[0])
