import json

import numpy as np
import open3d as o3d

from o3d_spectral.cli import main
from tests.conftest import sample_model


def test_register_prints_matrix_and_json(tmp_path, capsys):
    source = sample_model("mustard_bottle", 5000)
    T = np.eye(4)
    T[:3, 3] = [0.02, 0.0, -0.01]
    target = o3d.geometry.PointCloud(source).transform(T)
    o3d.io.write_point_cloud(str(tmp_path / "source.ply"), source)
    o3d.io.write_point_cloud(str(tmp_path / "target.pcd"), target)
    args = ["register", str(tmp_path / "source.ply"), str(tmp_path / "target.pcd"),
            "--voxel-size", "0.008"]
    assert main(args + ["--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(np.array(summary["transformation"])[:3, 3], T[:3, 3], atol=2e-3)
    assert summary["fitness"] > 0.99 and summary["converged"]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert np.loadtxt(lines[:4]).shape == (4, 4) and "fitness" in lines[4]


def test_register_reports_bad_input(tmp_path, capsys):
    assert main(["register", str(tmp_path / "missing.ply"), str(tmp_path / "missing.ply"),
                 "--voxel-size", "0.008"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_demo_writes_plot_and_result(tmp_path, capsys):
    assert main(["demo", "--object", "cracker_box", "--seed", "1", "--out", str(tmp_path)]) == 0
    assert "rotation error" in capsys.readouterr().out
    assert (tmp_path / "convergence.png").stat().st_size > 10_000
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["config"]["object"] == "cracker_box"
    assert result["rotation_error_deg"] < 5.0
