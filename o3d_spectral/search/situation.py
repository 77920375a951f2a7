"""Which kind of problem a registration is, decided once from the prepared clouds.

The global search runs different stages for different problems. :func:`situation` reads
the kind from the two clouds as :class:`o3d_spectral.SpectralStepper` prepared them, and
every stage takes its decision from the :class:`Situation` it returns.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from ..law.stepper import MovingCloud, SpectralStepper

__all__ = ["Kind", "Situation", "situation"]


class Kind(Enum):
    """What the moving cloud is matched against.

    - ``OBJECT``: the fixed cloud is about the moving cloud's size (a model against a
      model, a model against a view of it, a view against a model);
    - ``SCENE``: the fixed cloud holds more than the moving one (an object in a tabletop
      view, a crop in its frame): the search locates the object first, then focuses the
      fixed EGI about each place; no fit confirms a pose there, since a flat face fits a
      table as well as the object;
    - ``TWO_SCANS``: both clouds are single views of about one size (two scans of one
      thing): neither is culled, rotations also come from the grids' spectra and from a
      sweep of SO(3), the climbs are scored by the phase correlation alone and the best
      pose ascends the phase-correlation peak.
    """

    OBJECT = "object"
    SCENE = "scene"
    TWO_SCANS = "two scans"


@dataclass(frozen=True)
class Situation:
    """The kind of a registration problem.

    Attributes
    ----------
    kind : Kind
    culls : bool
        Whether the moving cloud is matched as the fixed cloud's sensor would see it (the
        fixed cloud is a single view, the moving one is not).
    """

    kind: Kind
    culls: bool

    @property
    def two_scans(self) -> bool:
        """``kind is Kind.TWO_SCANS``."""
        return self.kind is Kind.TWO_SCANS

    @property
    def scene(self) -> bool:
        """``kind is Kind.SCENE``."""
        return self.kind is Kind.SCENE


def situation(stepper: SpectralStepper, moving: MovingCloud) -> Situation:
    """The :class:`Situation` of registering ``moving`` against ``stepper``'s fixed cloud.

    A scene when the fixed cloud's grid holds more than the moving cloud
    (:meth:`o3d_spectral.spectra.target_grid.TargetGrid.holds_more`); otherwise two scans
    when both clouds were read as single views (``reading.view`` known on both); otherwise
    an object. The moving cloud is culled when the fixed cloud is a single view with a
    known sensor and the moving cloud is not (:meth:`o3d_spectral.SpectralStepper.sees`).
    """
    views = stepper.target_reading.view is not None and moving.reading.view is not None
    if stepper.grid.holds_more(moving.radius):
        kind = Kind.SCENE
    else:
        kind = Kind.TWO_SCANS if views else Kind.OBJECT
    return Situation(kind, stepper.sees(moving))
