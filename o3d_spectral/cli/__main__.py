"""``python -m o3d_spectral.cli``: the ``o3d-spectral`` command without the installed script."""

from o3d_spectral.cli import program

program()
