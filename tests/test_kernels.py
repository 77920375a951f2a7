import os
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.slow
def test_kernels_compile_ahead_from_the_command_line():
    """``python -m o3d_spectral.spectra.kernels`` compiles (or loads) every kernel and says so."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-m", "o3d_spectral.spectra.kernels"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("o3d_spectral kernels ready in ")
