"""``register``'s plain output rounds what it prints: no float at full precision."""

import re

import numpy as np
import open3d as o3d

from o3d_spectral.cli import main
from tests.conftest import sample_model


def test_register_plain_output_rounds_the_distance(tmp_path, capsys):
    source = sample_model("mustard_bottle", 3000)
    moved = o3d.geometry.PointCloud(source).translate(np.array([0.02, 0.0, -0.01]))
    paths = [tmp_path / "source.ply", tmp_path / "target.ply"]
    for path, cloud in zip(paths, (source, moved), strict=True):
        o3d.io.write_point_cloud(str(path), cloud)
    assert main(["register", *map(str, paths), "--voxel-size", str(1 / 130)]) == 0
    summary = capsys.readouterr().out.splitlines()[-1]
    assert "(at 0.007692 m)" in summary, summary
    assert not re.search(r"\d\.\d{7,}", summary), summary
