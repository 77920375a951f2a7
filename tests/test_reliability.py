"""Reliability: suites, runs and saved files are whole and what they claim to be."""

import json

import pytest

from o3d_spectral.harness.records import prepare_session, write_session
from o3d_spectral.synthetic.suite import MANIFEST, load_suite, make_suite


@pytest.fixture(scope="module")
def small_suite(tmp_path_factory):
    out = tmp_path_factory.mktemp("suites") / "sB"
    make_suite("full", 2, 0, out, progress=False)
    return out


def test_make_suite_refuses_a_folder_that_is_not_empty(small_suite):
    with pytest.raises(ValueError, match="sB.*not empty"):
        make_suite("full", 3, 0, small_suite, progress=False)


def test_make_suite_refuses_a_file_as_its_folder(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        make_suite("full", 1, 0, tmp_path / "file", progress=False)


def test_a_run_refuses_a_suite_rebuilt_in_place_with_the_same_seed(small_suite, tmp_path):
    """Same name, condition and seed, other content: its rows would not be its own."""
    run = tmp_path / "run"
    settings = {"voxel_size": 0.01, "seed": 0, "criteria": {}}
    entry = prepare_session(run, [load_suite(small_suite)], settings, ["m"])
    write_session(run, entry, {"id": "one", "started": "2026-01-01T00:00:00"})
    rebuilt = tmp_path / "sB"
    rebuilt.mkdir()
    manifest = json.loads((small_suite / MANIFEST).read_text())
    manifest["options"]["max_offset"] = 0.5
    (rebuilt / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="manifest changed"):
        prepare_session(run, [load_suite(rebuilt)], settings, ["m"])
    prepare_session(run, [load_suite(small_suite)], settings, ["m"])  # the same suite: resumed


# ---------------------------------------------------------------------- whole files


def _cloud(n=50):
    import numpy as np
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        np.random.default_rng(0).random((n, 3))))


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".xyz"])
def test_a_cloud_cut_short_by_a_full_disk_is_refused_and_the_old_file_kept(tmp_path, suffix):
    """Open3D's writer reports success on a full disk: the file written is checked."""
    import open3d as o3d

    from o3d_spectral.io.files import atomic_write_cloud

    path = tmp_path / f"moved{suffix}"
    path.write_bytes(b"old")
    cloud = _cloud()

    def full_disk(name):
        o3d.io.write_point_cloud(name, cloud)
        with open(name, "r+b") as file:
            file.truncate(file.seek(0, 2) // 2 if suffix != ".xyz" else 0)
        return True

    with pytest.raises(OSError, match=f"could not write .*moved\\{suffix}"):
        atomic_write_cloud(path, len(cloud.points), full_disk)
    assert path.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left
    atomic_write_cloud(path, len(cloud.points), lambda name: o3d.io.write_point_cloud(name, cloud))
    assert len(o3d.io.read_point_cloud(str(path)).points) == len(cloud.points)


def test_register_save_on_a_full_disk_fails_and_saves_nothing(tmp_path, monkeypatch, capsys):
    import open3d as o3d

    from o3d_spectral.cli import main

    source, target = tmp_path / "s.ply", tmp_path / "t.ply"
    cloud = _cloud(400)
    o3d.io.write_point_cloud(str(source), cloud)
    o3d.io.write_point_cloud(str(target), cloud)
    real = o3d.io.write_point_cloud

    def full_disk(name, geometry, *args, **kwargs):
        real(name, geometry, *args, **kwargs)
        with open(name, "r+b") as file:
            file.truncate(100)
        return True

    monkeypatch.setattr(o3d.io, "write_point_cloud", full_disk)
    status = main(["register", str(source), str(target), "--voxel-size", "0.1",
                   "--save", str(tmp_path / "moved.ply")])
    assert status != 0
    assert "moved.ply" in capsys.readouterr().err
    assert not (tmp_path / "moved.ply").exists()


def test_register_refuses_to_save_onto_its_source(tmp_path, capsys):
    import open3d as o3d

    from o3d_spectral.cli import main

    source, target = tmp_path / "s.ply", tmp_path / "t.ply"
    o3d.io.write_point_cloud(str(source), _cloud(400))
    o3d.io.write_point_cloud(str(target), _cloud(400))
    before = source.read_bytes()
    assert main(["register", str(source), str(target), "--voxel-size", "0.1",
                 "--save", str(tmp_path / "." / "s.ply")]) == 2
    assert "--save" in capsys.readouterr().err
    assert source.read_bytes() == before


# ---------------------------------------------------------------------- results rows

ROW = {"suite": "full", "index": 0, "method": "spectral", "success": True, "time_s": 0.5,
       "error": None, "rotation_error_deg": 1.0}


@pytest.mark.parametrize(("edit", "match"), [
    (lambda r: r.pop("success"), "line 2: not a results row: no 'success'"),
    (lambda r: r.__setitem__("success", "yes"), "line 2: 'success' must be true or false"),
    (lambda r: r.__setitem__("index", "0"), "line 2: 'index' must be an integer"),
    (lambda r: r.__setitem__("rotation_error_deg", "small"), "line 2: 'rotation_error_deg'"),
])
def test_report_refuses_a_row_missing_a_field_or_of_a_wrong_type(tmp_path, edit, match):
    from o3d_spectral.harness.report import run_summary

    bad = dict(ROW, index=1)
    edit(bad)
    path = tmp_path / "results.jsonl"
    path.write_text(json.dumps(ROW) + "\n" + json.dumps(bad) + "\n")
    with pytest.raises(ValueError, match=f"results.jsonl, {match}"):
        run_summary(path)


# ---------------------------------------------------------------------- CLI failures


def _cli(*args, stdout=None):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "o3d_spectral.cli", *args], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=300)


@pytest.fixture(scope="module")
def box_ply(tmp_path_factory):
    import open3d as o3d

    path = tmp_path_factory.mktemp("clouds") / "box.ply"
    cloud = o3d.geometry.TriangleMesh.create_box(0.1, 0.2, 0.3).sample_points_uniformly(2000)
    o3d.io.write_point_cloud(str(path), cloud)
    return path


def test_results_to_a_full_disk_fail_in_one_line(box_ply):
    with open("/dev/full", "w") as full:
        done = _cli("register", str(box_ply), str(box_ply), "--voxel-size", "0.02", "--json",
                    stdout=full)
    assert done.returncode == 1
    # a box onto itself: its half turns fit, a note (not shown at the default level)
    assert done.stderr.strip().splitlines() == [
        "o3d-spectral register: error: could not write the results to the standard output "
        "(No space left on device)"]


def test_a_bad_voxel_size_is_a_usage_error(box_ply):
    done = _cli("register", str(box_ply), str(box_ply), "--voxel-size", "-1")
    assert done.returncode == 2 and "--voxel-size" in done.stderr


def test_ctrl_c_is_one_line_and_status_130(box_ply, monkeypatch, capsys):
    from o3d_spectral.cli import main, register

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(register, "run", interrupted)
    assert main(["register", str(box_ply), str(box_ply), "--voxel-size", "0.02"]) == 130
    assert capsys.readouterr().err.strip() == "o3d-spectral register: interrupted"


@pytest.mark.parametrize("command", [["make-suite", "full", "--out", "{tmp}/s"],
                                     ["eval", "--suite", "{tmp}/s", "--out", "{tmp}/r"],
                                     ["demo", "--out", "{tmp}/d"], ["servo", "--out", "{tmp}/v"]])
@pytest.mark.parametrize("value", ["-1", "x"])
def test_a_bad_seed_is_a_usage_error_naming_seed(command, value, tmp_path, capsys):
    from o3d_spectral.cli import main

    argv = [a.replace("{tmp}", str(tmp_path)) for a in command] + ["--seed", value]
    assert main(argv) == 2
    assert "argument --seed: expected a non-negative integer" in capsys.readouterr().err
