import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.cli import main
from tests.conftest import sample_model


@pytest.mark.slow
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
    out, err = capsys.readouterr()
    summary = json.loads(out)
    np.testing.assert_allclose(np.array(summary["transformation"])[:3, 3], T[:3, 3], atol=2e-3)
    assert summary["fitness"] > 0.99 and summary["converged"]
    # the bottle's front and back fit alike, the model turned onto itself: a note says
    # so, nothing is warned about, the pose is kept
    assert summary["warnings"] == []
    assert summary["notes"] == ["symmetric: a pose 180 deg away fits as well, the source "
                                "turned onto itself: both are right (result.ambiguity)"]
    assert summary["confidence"] > 0.5 and summary["ambiguity_deg"] == pytest.approx(180, abs=5)
    twin = np.array(summary["ambiguous_transformation"])  # the other pose, half a turn away
    assert twin.shape == (4, 4) and np.allclose(twin[:3, :3] @ twin[:3, :3].T, np.eye(3))
    assert summary["source_normals"]["from"] == "given"
    assert summary["target_normals"]["view"] is None  # a whole model: no view, no culling
    assert summary["target_viewpoint"] is None
    assert "INFO" not in err  # default level: warnings and errors only
    assert main(["-v", *args]) == 0  # -v: INFO messages on stderr, stdout unchanged
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert np.loadtxt(lines[:4]).shape == (4, 4) and "fitness" in lines[4]
    assert "o3d-spectral: INFO: register done in" in err


def test_register_saves_the_moved_source_and_takes_viewpoints(tmp_path, capsys):
    """--save writes the source moved onto the target; --target-viewpoint none treats the
    target as a model; a malformed viewpoint is a usage error (exit 2)."""
    source = sample_model("mustard_bottle", 4000)
    T = np.eye(4)
    T[:3, 3] = [0.015, -0.01, 0.0]
    o3d.io.write_point_cloud(str(tmp_path / "source.ply"), source)
    o3d.io.write_point_cloud(str(tmp_path / "target.ply"),
                             o3d.geometry.PointCloud(source).transform(T))
    args = ["register", str(tmp_path / "source.ply"), str(tmp_path / "target.ply"),
            "--voxel-size", "0.008", "--init", str(tmp_path / "init.txt")]
    np.savetxt(tmp_path / "init.txt", np.eye(4))
    saved = tmp_path / "moved.ply"
    assert main([*args, "--target-viewpoint", "none", "--save", str(saved)]) == 0
    moved = np.asarray(o3d.io.read_point_cloud(str(saved)).points)
    expected = np.asarray(source.points) + T[:3, 3]
    assert np.abs(moved - expected).max() < 2e-3
    capsys.readouterr()
    assert main([*args, "--target-viewpoint", "0,0"]) == 2
    assert "--target-viewpoint" in capsys.readouterr().err


@pytest.mark.parametrize(("flag", "rotations"), [([], "auto"), (["--rotations", "dense"], "dense"),
                                               (["--rotations", "adaptive"], "adaptive")])
def test_register_passes_the_sweep_of_so3_to_the_global_call(
    tmp_path, monkeypatch, capsys, flag, rotations,
):
    given = []
    registration = o3d_spectral.registration_spectral_global

    def spied(*arguments, **options):
        given.append(options["search"].rotations)
        return registration(*arguments, **options)

    monkeypatch.setattr(o3d_spectral, "registration_spectral_global", spied)
    source = sample_model("mustard_bottle", 3000)
    o3d.io.write_point_cloud(str(tmp_path / "source.ply"), source)
    o3d.io.write_point_cloud(str(tmp_path / "target.ply"), source)
    assert main(["register", str(tmp_path / "source.ply"), str(tmp_path / "target.ply"),
                 "--voxel-size", "0.008", *flag]) == 0
    assert given == [rotations]
    capsys.readouterr()
    assert main(["register", "a.ply", "b.ply", "--voxel-size", "0.008", "--rotations",
                 "fast"]) == 2
    assert "--rotations" in capsys.readouterr().err


def test_register_offers_every_sweep_of_so3_the_option_takes():
    from o3d_spectral.cli import build_parser
    from o3d_spectral.search.options import ROTATIONS

    for rotations in ROTATIONS:
        args = build_parser().parse_args(["register", "a.ply", "b.ply", "--voxel-size",
                                          "0.008", "--rotations", rotations])
        assert o3d_spectral.GlobalSearchOption(rotations=args.rotations).rotations == rotations


def test_register_reports_bad_input(tmp_path, capsys):
    """A failed run exits 1 with one line naming the file; the traceback only with -vv."""
    missing = tmp_path / "missing.ply"
    assert main(["register", str(missing), str(missing), "--voxel-size", "0.008"]) == 1
    assert capsys.readouterr().err == f"o3d-spectral register: error: no such file: {missing}\n"
    empty = tmp_path / "empty.ply"
    empty.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n")
    assert main(["register", str(empty), str(empty), "--voxel-size", "0.008"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err and str(empty) in err
    assert main(["-vv", "register", str(empty), str(empty), "--voxel-size", "0.008"]) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err
    assert f"\no3d-spectral register: error: {empty}: Open3D read no points from it" in err


def test_version_and_usage_errors(capsys):
    assert main(["--version"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"o3d-spectral {o3d_spectral.__version__}"
    assert [line.split()[0] for line in lines[1:]] == ["open3d", "numpy", "scipy", "python"]
    assert lines[1] == f"open3d {o3d.__version__}" and lines[2] == f"numpy {np.__version__}"
    # argparse's errors, and our own checks of option values before running, exit 2
    assert main(["register", "--voxel-size", "x"]) == 2
    assert "usage:" in capsys.readouterr().err
    assert main(["-v", "-q", "demo"]) == 2
    assert "not allowed" in capsys.readouterr().err
    assert main(["demo", "--max-angle", "400"]) == 2
    assert capsys.readouterr().err == (
        "o3d-spectral demo: error: --max-angle must be in [0, 180] degrees, got 400.0\n"
    )


def test_library_logs_nothing_unless_configured():
    """The package logger has a NullHandler: without logging configured, a warning from the
    library prints nothing (not Python's last-resort stderr output). In a fresh interpreter,
    since pytest configures logging in this one."""
    code = (
        "import logging, o3d_spectral\n"
        "assert any(isinstance(h, logging.NullHandler)"
        " for h in logging.getLogger('o3d_spectral').handlers)\n"
        "logging.getLogger('o3d_spectral.registration').warning('should not be printed')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "" and done.stderr == ""


@pytest.mark.slow
def test_demo_writes_plot_and_result(tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the harness extra is not installed")
    assert main(["demo", "--object", "cracker_box", "--seed", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "rotation error" in out
    # the errors printed are the refined result's; the plot's last law iterate is named too
    assert "after the final ICP polish" in out and "at the law's last iteration" in out
    assert (tmp_path / "convergence.png").stat().st_size > 10_000
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["config"]["object"] == "cracker_box"
    assert result["rotation_error_deg"] < 5.0
    assert result["convergence_plot"] == str(tmp_path / "convergence.png")
    assert f"{result['law_rotation_error_deg']:.2f} deg at the law's last iteration" in out


def test_register_init_and_voxel_size_errors_name_the_option_and_file(tmp_path, capsys):
    """A pose written with 5 decimals is taken (made rigid); a sheared one is refused
    naming --init and its file; a NaN voxel size names --voxel-size."""
    from scipy.spatial.transform import Rotation

    source = sample_model("mustard_bottle", 3000)
    o3d.io.write_point_cloud(str(tmp_path / "source.ply"), source)
    init = np.eye(4)
    init[:3, :3] = Rotation.from_euler("xyz", [3, -2, 4], degrees=True).as_matrix()
    path = tmp_path / "init.txt"
    np.savetxt(path, init, fmt="%.5f")
    args = ["register", str(tmp_path / "source.ply"), str(tmp_path / "source.ply"),
            "--voxel-size", "0.008", "--init", str(path), "--max-iteration", "3"]
    assert main(args) == 0
    capsys.readouterr()
    init[0, 1] += 0.01
    np.savetxt(path, init, fmt="%.5f")
    assert main(args) == 1
    err = capsys.readouterr().err
    assert f"--init {path}" in err and "rigid" in err and len(err.splitlines()) == 1
    assert main([*args[:3], "--voxel-size", "nan"]) == 2  # a usage error
    assert "--voxel-size" in capsys.readouterr().err
