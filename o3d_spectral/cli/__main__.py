"""``python -m o3d_spectral.cli``: the ``o3d-spectral`` command without the installed script."""

import sys

from o3d_spectral.cli import main

sys.exit(main())
