"""Numeric constants of the control law (``o3d_spectral.law``), by the module using them."""

# -- law.centring: the centred frame -------------------------------------------------------

#: Targets whose centroid lies farther than this from the origin (metres) are centred:
#: all of them (a registration must not depend on where the frame's origin is).
CENTRE_DISTANCE = 0.0


# -- law.stepper: the stepper --------------------------------------------------------------

#: :meth:`SpectralStepper.focused` keeps the whole EGI when the points it is given keep
#: over this share of the fixed cloud's normals.
FOCUS_SHARE = 0.9
#: Largest table of harmonics (bytes) kept for a moving cloud's visible EGI
#: (:attr:`MovingCloud.harmonics`); beyond it the visible normals are projected anew.
MAX_HARMONICS_TABLE = 64 * 2**20
