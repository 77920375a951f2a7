"""BOP-layout datasets and 3DMatch-layout scan pairs: reading, scoring, eval and report."""

from __future__ import annotations

import json
import shutil

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.cli import main
from o3d_spectral.harness import bop_write, pose_metrics
from o3d_spectral.harness.bop import BopSet, symmetry_of
from o3d_spectral.harness.pairs import PairSet, information_rmse, read_log, write_log
from o3d_spectral.harness.real import real_dir, write_dragon_pairs
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.symmetry import Symmetry
from tests.latex import compile_tables

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
SHAPE = (480, 640)
BOX = (0.06, 0.04, 0.02)


def _pose(axis, degrees: float, translation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(degrees) * np.asarray(axis, dtype=float))
    T[:3, 3] = translation
    return T


def _box() -> o3d.geometry.TriangleMesh:
    mesh = o3d.geometry.TriangleMesh.create_box(*BOX)
    mesh.translate(-0.5 * np.asarray(BOX))
    mesh.compute_vertex_normals()
    return o3d.geometry.TriangleMesh(mesh.subdivide_midpoint(3))


def _half_turn() -> Symmetry:
    """The box's half turn about its z axis (one of its symmetries)."""
    return Symmetry(discrete=np.stack([np.eye(4), _pose((0, 0, 1), 180.0, np.zeros(3))]))


T_GT = _pose((1, 1, 0) / np.sqrt(2), 35.0, (0.02, -0.01, 0.5))


@pytest.fixture
def bop_dir(tmp_path):
    """A one-image BOP dataset: the box (object 5) at ``T_GT`` before a wall 0.7 m away."""
    root = tmp_path / "boxes"
    mesh = _box()
    bop_write.write_model(root, 5, mesh, _half_turn())
    rendered = pose_metrics.render_depth(mesh, T_GT, K, SHAPE)
    depth = np.where(rendered > 0, rendered, 0.7)
    bop_write.write_image(root / "test" / "000003", 7, depth, K,
                          [(5, T_GT, rendered > 0, 1.0)])
    return root


def test_a_written_bop_dataset_reads_back(bop_dir):
    crops, frames = (BopSet(bop_dir, "test", kind) for kind in ("crop", "frame"))
    assert len(crops) == len(frames) == 1
    crop = crops[0]
    np.testing.assert_allclose(crop.T_gt, T_GT, atol=1e-9)
    assert crop.metadata["object"] == "obj_000005" and crop.metadata["scene"] == 3
    # The crop's points lie on the posed box (depth kept to 0.1 mm).
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(_box().transform(T_GT)))
    points = np.asarray(crop.target.points, dtype=np.float32)
    assert np.max(scene.compute_distance(o3d.core.Tensor(points)).numpy()) < 2e-4
    assert len(frames[0].target.points) > 10 * len(crop.target.points)  # the wall too
    assert len(crop.symmetry.discrete) == 2
    diameter = float(np.linalg.norm(BOX))
    score = crops.score(T_GT, 0)
    assert score["diameter_m"] == pytest.approx(diameter, rel=1e-6)
    assert score["vsd"] == [0.0] * 10 and score["mssd_m"] < 1e-9 and score["mspd_px"] < 1e-6
    # The half turn is a symmetry in models_info.json: MSSD and MSPD accept it, and so
    # does VSD, which sees the same surface.
    turned = crops.score(T_GT @ _pose((0, 0, 1), 180.0, np.zeros(3)), 0)
    assert turned["mssd_m"] < 1e-6 and turned["mspd_px"] < 1e-4
    assert max(turned["vsd"]) < 0.02


def test_bop_errors_name_the_missing_file(bop_dir):
    (bop_dir / "test" / "000003" / "scene_gt.json").unlink()
    with pytest.raises(FileNotFoundError, match="scene_gt.json"):
        BopSet(bop_dir)
    with pytest.raises(FileNotFoundError, match="models_info.json"):
        BopSet(bop_dir / "test")
    with pytest.raises(FileNotFoundError, match="split folder"):
        BopSet(bop_dir, "val")


def test_bop_selection(bop_dir):
    assert len(BopSet(bop_dir, scenes=(3,), objects=(5,))) == 1
    with pytest.raises(ValueError, match="no annotated objects"):
        BopSet(bop_dir, objects=(1,))


def test_models_info_symmetries_in_metres():
    continuous = symmetry_of(
        {"symmetries_continuous": [{"axis": [0, 0, 2], "offset": [0, 0, 10]}]}, "here")
    np.testing.assert_allclose(continuous.axis, (0, 0, 1))
    np.testing.assert_allclose(continuous.center, (0, 0, 0.01))
    flip = np.diag([-1.0, -1.0, 1.0, 1.0])
    flip[0, 3] = 20.0  # mm
    discrete = symmetry_of({"symmetries_discrete": [flip.ravel().tolist()]}, "here")
    assert len(discrete.discrete) == 2 and discrete.discrete[1][0, 3] == pytest.approx(0.02)
    with pytest.raises(ValueError, match="here: bad symmetries"):
        symmetry_of({"symmetries_continuous": [{"axis": [0, 0, 1]}] * 2}, "here")


def test_the_bundled_ycbv_frame_in_bop_layout():
    root = real_dir().parent / "bop_ycbv"
    crops = BopSet(root)
    assert [crops[i].metadata["object"] for i in range(3)] == [
        "obj_000008", "obj_000014", "obj_000021"]  # gelatin box, mug, foam brick
    truth = np.loadtxt(real_dir() / "ycbv" / "0000_000001" / "025_mug_T_cam_from_model.txt")
    np.testing.assert_allclose(crops[1].T_gt, truth, atol=1e-5)
    assert crops.score(crops[1].T_gt, 1)["vsd"] == [0.0] * 10
    assert len(crops[2].symmetry.discrete) == 8  # the foam brick's square section


@pytest.fixture
def pairs_dir(tmp_path):
    """A 3DMatch-layout scene: a box sampled twice, pair (0, 1) turned 20 degrees."""
    scene = tmp_path / "pairs" / "boxes"
    scene.mkdir(parents=True)
    mesh = _box()
    o3d.utility.random.seed(0)
    cloud = mesh.sample_points_uniformly(3000, use_triangle_normal=True)
    move = _pose((0, 0, 1), 20.0, (0.01, 0.0, 0.0))
    o3d.io.write_point_cloud(str(scene / "cloud_bin_0.ply"), cloud)
    o3d.io.write_point_cloud(str(scene / "cloud_bin_1.ply"),
                             o3d.geometry.PointCloud(cloud).transform(np.linalg.inv(move)))
    write_log(scene / "gt.log", {(0, 1): move}, 2)
    write_log(scene / "gt.info", {(0, 1): np.eye(6)}, 2)
    return scene


def test_pairs_read_and_score(pairs_dir):
    pairs = PairSet(pairs_dir)
    pair = pairs[0]
    moved = np.asarray(o3d.geometry.PointCloud(pair.source).transform(pair.T_gt).points)
    np.testing.assert_allclose(moved, np.asarray(pair.target.points), atol=1e-6)
    exact = pairs.score(pair.T_gt, 0)
    assert exact == {"re_deg": 0.0, "te_m": 0.0, "recalled": True,
                     "rmse_m": pytest.approx(0.0, abs=1e-12), "rmse_recalled": True}
    off = pair.T_gt @ _pose((1, 0, 0), 16.0, np.zeros(3))
    assert pairs.score(off, 0)["re_deg"] == pytest.approx(16.0)
    assert not pairs.score(off, 0)["recalled"]
    far = pair.T_gt.copy()
    far[2, 3] += 0.31
    assert not pairs.score(far, 0)["recalled"]


def _information(points):
    """``gt.info``'s matrix by hand: the sum of ``J^T J``, ``J = [I, -2 [p]x]``."""
    def jacobian(p):
        skew = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
        return np.hstack([np.eye(3), -2 * skew])
    return sum(jacobian(p).T @ jacobian(p) for p in np.asarray(points, float))


def test_information_rmse_by_hand():
    information = _information([(1, 0, 0), (0, 2, 0)])
    slide = _pose((0, 0, 1), 0.0, (0.03, 0.04, 0.0))
    assert information_rmse(slide, np.eye(4), information) == pytest.approx(0.05)
    # A 60 degree turn about z: the points travel chords 2 r sin(30 deg) = r, of mean
    # square (1 + 4) / 2.
    turn = _pose((0, 0, 1), 60.0, np.zeros(3))
    assert information_rmse(turn, np.eye(4), information) == pytest.approx(np.sqrt(2.5))
    # The error is measured from the truth: inv(T_gt) @ T.
    truth = _pose((1, 1, 0), 40.0, (1.0, -2.0, 0.5))
    assert information_rmse(truth @ turn, truth, information) == pytest.approx(np.sqrt(2.5))
    assert information_rmse(truth, truth, information) == pytest.approx(0.0, abs=1e-12)


def test_pairs_score_both_recalls(pairs_dir):
    pairs = PairSet(pairs_dir)
    off = pairs[0].T_gt @ _pose((0, 0, 1), 0.0, (0.15, 0.0, 0.0))
    score = pairs.score(off, 0)
    assert score["rmse_m"] == pytest.approx(0.15) and score["rmse_recalled"]  # gt.info: I
    assert not pairs.score(pairs[0].T_gt @ _pose((0, 0, 1), 0.0, (0.25, 0, 0)),
                           0)["rmse_recalled"]
    (pairs_dir / "gt.info").unlink()
    score = PairSet(pairs_dir).score(off, 0)
    assert score["rmse_m"] is None and score["rmse_recalled"] is None and score["recalled"]


def test_gt_info_not_positive_semi_definite_is_named(pairs_dir):
    for matrix in (np.diag([1.0, 1, 1, 1, 1, -1]), np.eye(6) + np.eye(6, k=1),
                   np.diag([0.0, 1, 1, 1, 1, 1])):
        write_log(pairs_dir / "gt.info", {(0, 1): matrix}, 2)
        with pytest.raises(ValueError, match=r"gt.info, pair 0 1 \(line 1\): information"):
            PairSet(pairs_dir)


def test_pairs_errors_and_evaluation_folder(pairs_dir):
    evaluation = pairs_dir.parent / "boxes-evaluation"
    evaluation.mkdir()
    for name in ("gt.log", "gt.info"):
        (pairs_dir / name).rename(evaluation / name)
    assert len(PairSet(pairs_dir)) == 1  # 3DMatch ships the truth beside the fragments
    (evaluation / "gt.log").unlink()
    with pytest.raises(FileNotFoundError, match="gt.log"):
        PairSet(pairs_dir)
    (evaluation / "gt.log").write_text("0 1 2\n1 0 0\n")
    with pytest.raises(ValueError, match="gt.log, line 1"):
        read_log(evaluation / "gt.log")


def test_dragon_pairs_in_3dmatch_layout(tmp_path):
    pairs = PairSet(write_dragon_pairs(tmp_path / "dragon"))
    assert len(pairs) == 18 and pairs.keys[0] == (0, 1)  # 7 + 6 + 5 pairs 24-72 deg apart
    pair = pairs[0]
    fit = o3d.pipelines.registration.evaluate_registration(
        pair.source, pair.target, 0.002, pair.T_gt)
    assert fit.fitness > 0.8  # scan 24 deg onto scan 0: about 91% overlap
    assert len(read_log(tmp_path / "dragon" / "gt.info", 6)) == 18
    # gt.info in the benchmark's convention: for a small error its RMSE is the RMSE the
    # error moves the overlap's points by (second order: within a few percent).
    error = _pose((0.3, -1, 0.5), 0.5, (0.001, -0.002, 0.0005))
    source = np.asarray(pair.source.points)
    moved = source @ error[:3, :3].T + error[:3, 3]
    target = o3d.geometry.KDTreeFlann(o3d.geometry.PointCloud(pair.target).transform(
        np.linalg.inv(pair.T_gt)))
    overlap = [k for k, p in enumerate(source) if target.search_radius_vector_3d(p, 0.002)[0]]
    direct = np.sqrt(np.mean(np.sum((moved - source)[overlap] ** 2, axis=1)))
    assert pairs.score(pair.T_gt @ error, 0)["rmse_m"] == pytest.approx(direct, rel=0.02)


@pytest.mark.slow
def test_eval_and_report_on_both_benchmarks(bop_dir, pairs_dir, tmp_path, capsys):
    out = tmp_path / "run"
    for shard in ("0/2", "1/2"):
        assert main(["eval", "--bop", str(bop_dir), "--pairs", str(pairs_dir), "--methods",
                     "icp_point_to_plane", "--shard", shard, "--out", str(out)]) == 0
    rows = [json.loads(line) for file in (out / "results").glob("*.jsonl")
            for line in file.read_text().splitlines()]
    assert sorted(r["suite"] for r in rows) == ["boxes", "boxes_test_crop", "boxes_test_frame"]
    assert main(["report", str(out), "--out", str(tmp_path / "report")]) == 0
    bop = (tmp_path / "report" / "bop.md").read_text()
    assert "boxes_test_crop" in bop and "boxes_test_frame" in bop
    pairs = (tmp_path / "report" / "pairs.md").read_text()
    assert "| boxes | icp_point_to_plane | 1 |" in pairs
    if shutil.which("pdflatex") and shutil.which("pdftotext"):
        tables = sorted((tmp_path / "report").glob("*.tex"))
        assert {"bop.tex", "pairs.tex"} <= {path.name for path in tables}
        text = compile_tables([path.read_text() for path in tables], tmp_path / "tex")
        assert "recall RMSE (%)" in text and "boxes_test_crop" in text
    assert main(["eval", "--out", str(out)]) == 2
    assert main(["eval", "--suite", str(out), "--scenes", "1", "--out", str(out)]) == 2
    assert "go with --bop" in capsys.readouterr().err


def test_the_report_tables_count_by_hand():
    """Two BOP rows: one exact, one that raised (wrong everywhere): every recall 0.5. Two
    pairs: one recalled (2 degrees, 1 cm), one not: recall 0.5, RE 2, TE 1 cm."""
    import pandas as pd

    from o3d_spectral.harness.tables import bop_table, pairs_table
    from o3d_spectral.harness.writers import to_markdown

    common = {"method": "m", "time_s": 1.0}
    bop = pd.DataFrame([
        {"suite": "s_crop", "condition": "bop_crop", "index": 0, "success": True,
         "vsd": [0.0] * 10, "mssd_m": 0.0, "mspd_px": 0.0, "diameter_m": 0.1,
         "image_width_px": 640, **common},
        {"suite": "s_crop", "condition": "bop_crop", "index": 1, "success": False, **common},
    ])
    row = bop_table(bop).frame.iloc[0]
    assert (row["n"], row["AR"], row["AR VSD"], row["AR MSSD"], row["AR MSPD"]) == (
        2, 0.5, 0.5, 0.5, 0.5)
    pairs = pd.DataFrame([
        {"suite": "scene", "condition": "pairs", "index": 0, "success": True,
         "recalled": True, "re_deg": 2.0, "te_m": 0.01, "rmse_m": 0.1,
         "rmse_recalled": True, **common},
        {"suite": "scene", "condition": "pairs", "index": 1, "success": False,
         "recalled": False, "re_deg": 40.0, "te_m": 0.5, "rmse_m": 0.15,
         "rmse_recalled": True, **common},
        {"suite": "scene", "condition": "pairs", "index": 2, "success": False, **common},
        {"suite": "no_info", "condition": "pairs", "index": 0, "success": True,
         "recalled": True, "re_deg": 1.0, "te_m": 0.02, "rmse_m": None,
         "rmse_recalled": None, **common},
    ])
    table = pairs_table(pairs)
    rows = table.frame.set_index("scene")
    row = rows.loc["scene"]  # a run that raised counts as recalled by neither
    assert (row["pairs"], row["recall RE/TE (%)"], row["recall RMSE (%)"]) == (3, 1 / 3, 2 / 3)
    assert (row["RE (deg)"], row["TE (cm)"]) == (2.0, 1.0)
    unscored = rows.loc["no_info"]
    assert unscored["recall RE/TE (%)"] == 1.0 and pd.isna(unscored["recall RMSE (%)"])
    assert "| no_info | m | 1 | 100.0 | – |" in to_markdown(table)
    assert "a dash where the scene has no `gt.info`" in table.caption


def test_mspd_of_a_pose_behind_the_camera_is_infinite():
    points = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    assert pose_metrics.mspd(np.eye(4), T_GT, points, K) == np.inf


def test_eval_says_the_rmse_recall_is_unavailable_without_gt_info(pairs_dir, tmp_path, capsys):
    (pairs_dir / "gt.info").unlink()
    assert main(["eval", "--pairs", str(pairs_dir), "--methods", "icp_point_to_plane",
                 "--out", str(tmp_path / "run")]) == 0
    assert "no gt.info beside gt.log" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "run"), "--out", str(tmp_path / "report")]) == 0
    row = (tmp_path / "report" / "pairs.md").read_text().splitlines()[-1]
    assert row.startswith("| boxes | icp_point_to_plane | 1 | 100.0 | – |"), row
