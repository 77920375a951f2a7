"""Numeric constants of the command line (``o3d_spectral.cli``), by the module using them."""

import numpy as np

# -- cli._output: what a command writes ----------------------------------------------------

#: Seconds a command runs before its status line appears, and between redraws.
STATUS_DELAY, STATUS_INTERVAL = 2.0, 0.5


# -- cli.reconstruct: reconstruct ----------------------------------------------------------

#: Points drawn in the picture at most (a random, seeded subset beyond).
PICTURE_POINTS = 30_000


# -- cli.servo: servo ----------------------------------------------------------------------

#: A servoing run succeeds when it ends within 5 mm and 1 degree of the goal (the paper's
#: second experiment reports its final errors against these).
SUCCESS_TRANSLATION = 0.005  # m
SUCCESS_ROTATION = np.deg2rad(1.0)


# -- cli.stops: early stops ----------------------------------------------------------------

#: Exit status after the reader of the standard output went away: 128 + SIGPIPE, as a
#: program the signal ended (``yes | head -1``).
BROKEN_PIPE_STATUS = 141
