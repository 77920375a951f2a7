"""The bundled data is package data, found through ``importlib.resources`` wherever the
package is imported from: installed files, or a zip archive (extracted once per process)."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from o3d_spectral.common import bundled
from o3d_spectral.synthetic import models

PACKAGE = Path(bundled.__file__).resolve().parents[1]


def test_data_is_found_inside_the_package():
    objects = bundled.data_folder("objects")
    assert objects == PACKAGE / "datasets" / "objects"
    assert "mug" in models.model_names()
    assert bundled.data_folder("no such folder") is None


def test_environment_variable_comes_first_and_errors_name_it(monkeypatch, tmp_path):
    (tmp_path / "cube.ply").write_bytes((PACKAGE / "datasets/objects/mug.ply").read_bytes())
    monkeypatch.setenv("O3D_SPECTRAL_DATA", str(tmp_path))
    assert models.objects_dir() == tmp_path and models.model_names() == ["cube"]
    with pytest.raises(FileNotFoundError, match="O3D_SPECTRAL_MISSING"):
        bundled.bundled_folder("objects", "O3D_SPECTRAL_MISSING", lambda folder: False, "x")


def _zipped_package(path: Path) -> Path:
    """The package's modules and two bundled meshes in the zip archive ``path``."""
    with zipfile.ZipFile(path, "w") as archive:
        for module in PACKAGE.rglob("*.py"):
            archive.write(module, module.relative_to(PACKAGE.parent))
        for mesh in ("mug", "bowl"):
            file = PACKAGE / "datasets" / "objects" / f"{mesh}.ply"
            archive.write(file, file.relative_to(PACKAGE.parent))
    return path


@pytest.mark.slow
def test_a_zip_import_reads_the_data_from_an_extracted_copy(tmp_path):
    archive = _zipped_package(tmp_path / "o3d_spectral.zip")
    code = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "import o3d_spectral\n"
        "assert o3d_spectral.__file__.startswith(sys.argv[1]), o3d_spectral.__file__\n"
        "from o3d_spectral.synthetic import models\n"
        "folder = models.objects_dir()\n"
        "assert folder.is_dir() and not str(folder).startswith(sys.argv[1])\n"
        "print(folder, models.model_names(), len(models.load_model('mug').vertices))\n"
    )
    done = subprocess.run([sys.executable, "-I", "-c", code, str(archive)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    folder, names = done.stdout.split(" ", 1)
    assert names.startswith("['bowl', 'mug'] ") and int(names.split()[-1]) > 1000
    assert not Path(folder).exists()  # the extracted copy is removed at exit
