"""registration_multiway and ``o3d-spectral reconstruct``: scans in any frames, one model."""

from __future__ import annotations

import json

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.cli import main
from o3d_spectral.common.pose_errors import rotation_error, translation_error
from o3d_spectral.harness import real
from o3d_spectral.multiway import registration as multiway_registration
from o3d_spectral.multiway.graph import tree_weight
from o3d_spectral.multiway.registration import poses_from_pairs
from o3d_spectral.synthetic.models import model_path
from tests.conftest import sample_model

VOXEL = 0.005


def turned_dragon(angles: tuple[int, ...], seed: int) -> tuple[list, list]:
    """The dragon scans at ``angles``, each turned by a random rotation: (clouds, their
    world_from_cloud poses)."""
    rng = np.random.default_rng(seed)
    clouds, poses = [], []
    for angle in angles:
        path = real.real_dir() / "dragon" / f"dragonStandRight_{angle}.ply"
        motion = np.eye(4)
        motion[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        clouds.append(o3d.io.read_point_cloud(str(path)).transform(motion))
        poses.append(real.dragon_pose(angle) @ np.linalg.inv(motion))
    return clouds, poses


def drill() -> o3d.geometry.PointCloud:
    """A view-less cloud of another object, the size of the dragon."""
    mesh = o3d.io.read_triangle_mesh(str(model_path("power_drill")))
    return o3d.geometry.PointCloud(mesh.vertices)


@pytest.fixture(scope="module")
def dragon_and_drill():
    """Four dragon scans and a drill, registered: (clouds, truths, copies, result)."""
    clouds, truths = turned_dragon((0, 24, 48, 72), seed=3)
    clouds.append(drill())
    copies = [np.asarray(c.points).copy() for c in clouds]
    option = o3d_spectral.MultiwayOption(workers=2)
    return clouds, truths, copies, o3d_spectral.registration_multiway(clouds, VOXEL,
                                                                      option=option)


@pytest.mark.slow
def test_the_dragon_scans_are_placed_within_5_degrees_and_1_cm(dragon_and_drill):
    clouds, truths, _, result = dragon_and_drill
    assert result.poses[0].tolist() == np.eye(4).tolist()
    for k, truth in enumerate(truths):
        pose, expected = result.poses[k], np.linalg.inv(truths[0]) @ truth
        centre = np.asarray(clouds[k].points).mean(axis=0)
        assert pose.dtype == np.float64 and np.allclose(pose[:3, :3] @ pose[:3, :3].T,
                                                        np.eye(3))
        assert rotation_error(pose, expected) < 5.0
        assert translation_error(pose, expected, center=centre) < 0.01
    assert len(result.pairs) == 10 and result.nodes == (0, 1, 2, 3)
    assert len(result.pose_graph.nodes) == 4


@pytest.mark.slow
def test_a_cloud_of_another_object_is_reported_unconnected(dragon_and_drill):
    clouds, _, copies, result = dragon_and_drill
    assert result.unconnected == (4,) and result.poses[4] is None
    assert not any(p.kept for p in result.pairs if 4 in (p.source, p.target))
    for cloud, points in zip(clouds, copies, strict=True):  # the caller's clouds untouched
        np.testing.assert_array_equal(np.asarray(cloud.points), points)


def test_fewer_than_two_clouds_are_refused():
    clouds, _ = turned_dragon((0,), seed=0)
    with pytest.raises(ValueError, match="clouds must hold at least two"):
        o3d_spectral.registration_multiway(clouds, VOXEL)
    with pytest.raises(TypeError, match="clouds must be a sequence"):
        o3d_spectral.registration_multiway(clouds[0], VOXEL)


def test_clouds_in_different_units_are_refused_naming_both_extents():
    points = np.asarray(turned_dragon((0,), seed=0)[0][0].points)
    millimetres = 1000.0 * points
    with pytest.raises(ValueError, match=r"clouds\[1\] spans .* m and clouds\[0\] .* m "
                                         r"\(1000x\): are the clouds in the same units"):
        o3d_spectral.registration_multiway([points, millimetres], VOXEL)
    assert np.array_equal(millimetres, 1000.0 * points)  # not scaled in place


def test_the_result_is_the_same_whatever_the_workers():
    clouds, truths = turned_dragon((0, 24, 48), seed=5)
    arrays = [np.asarray(c.points) for c in clouds]  # numpy input too
    results = [o3d_spectral.registration_multiway(
        arrays, 0.008, option=o3d_spectral.MultiwayOption(workers=w, refine=True))
        for w in (1, 2)]  # the refinement too
    for k, (one, two) in enumerate(zip(results[0].poses, results[1].poses, strict=True)):
        np.testing.assert_array_equal(one, two)
        assert rotation_error(one, np.linalg.inv(truths[0]) @ truths[k]) < 5.0
    assert [(p.source, p.target, p.fit) for p in results[0].pairs] == [
        (p.source, p.target, p.fit) for p in results[1].pairs]


def test_options_are_checked_naming_the_field():
    with pytest.raises(ValueError, match="min_fit"):
        o3d_spectral.MultiwayOption(min_fit=1.5)
    with pytest.raises(TypeError, match="workers"):
        o3d_spectral.MultiwayOption(workers=1.5)
    with pytest.raises(TypeError, match="search"):
        o3d_spectral.MultiwayOption(search="dense")


@pytest.mark.parametrize("search", [None, o3d_spectral.GlobalSearchOption(rotations="dense")])
def test_the_pairwise_calls_search_as_the_option_says(monkeypatch, search):
    """Adaptive by default (most pairs of an unordered set share nothing, and the single
    call's CPU default would send each to the dense search too); as given otherwise."""
    given = []
    registration = multiway_registration.registration_spectral_global

    def spied(*arguments, **options):
        given.append(options["search"])
        return registration(*arguments, **options)

    monkeypatch.setattr(multiway_registration, "registration_spectral_global", spied)
    option = (o3d_spectral.MultiwayOption() if search is None
              else o3d_spectral.MultiwayOption(search=search))
    clouds, _ = turned_dragon((0, 24), seed=3)
    o3d_spectral.registration_multiway(clouds, 0.008, option=option)
    expected = search or o3d_spectral.GlobalSearchOption(rotations="adaptive")
    assert given == [expected]


@pytest.mark.slow
def test_reconstruct_writes_the_cloud_the_poses_and_a_picture(tmp_path, capsys):
    clouds, _ = turned_dragon((0, 24, 48), seed=7)
    paths = []
    for k, cloud in enumerate(clouds):
        paths.append(tmp_path / f"scan{k}.ply")
        o3d.io.write_point_cloud(str(paths[-1]), cloud)
    out = tmp_path / "out"
    assert main(["-q", "reconstruct", *map(str, paths), "--voxel-size", "0.008", "--out",
                 str(out), "--json", "--workers", "2"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert sorted(p.name for p in out.iterdir()) == ["merged.ply", "merged.png",
                                                     "poses.json"]  # no temporary left
    assert json.loads((out / "poses.json").read_text())["poses"] == printed["poses"]
    assert printed["unconnected"] == [] and len(printed["poses"]) == 3
    assert printed["doubtful"] == [] and all(0.0 <= p["confidence"] <= 1.0
                                             for p in printed["pairs"])
    merged = o3d.io.read_point_cloud(str(out / "merged.ply"))
    assert len(merged.points) > max(len(c.voxel_down_sample(0.004).points) for c in clouds)
    assert (out / "merged.png").read_bytes()[:4] == b"\x89PNG"
    _a_stopped_run_leaves_no_set_that_looks_complete(paths, out, capsys)


def _a_stopped_run_leaves_no_set_that_looks_complete(paths, out, capsys):
    """A second run into ``out`` stopped midway: the first run's outputs wait aside."""
    from o3d_spectral.cli import reconstruct
    from o3d_spectral.cli.stops import Terminated

    first = (out / "poses.json").read_text()

    def stopped(args):
        raise Terminated

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(reconstruct, "register_and_write", stopped)
        assert main(["reconstruct", *map(str, paths), "--voxel-size", "0.008", "--out",
                     str(out)]) == 143
    assert "o3d-spectral reconstruct: terminated" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["previous_run"]
    assert (out / "previous_run" / "poses.json").read_text() == first
    assert main(["-q", "reconstruct", *map(str, paths), "--voxel-size", "0.008", "--out",
                 str(out)]) == 0  # complete again: the set aside is gone
    assert sorted(p.name for p in out.iterdir()) == ["merged.ply", "merged.png", "poses.json"]


@pytest.mark.parametrize(("flag", "cameras"), [([], None), (["--sensor-frames"], [[0.0] * 3] * 2)])
def test_reconstruct_gives_the_cameras_at_the_origin_with_sensor_frames(
    tmp_path, monkeypatch, flag, cameras,
):
    given = []
    registration = o3d_spectral.registration_multiway

    def spied(clouds, voxel_size, **options):
        locations = options["camera_locations"]
        given.append(None if locations is None else [list(c) for c in locations])
        return registration(clouds, voxel_size, **options)

    monkeypatch.setattr(o3d_spectral, "registration_multiway", spied)
    paths = []
    for k, cloud in enumerate(turned_dragon((0, 24), seed=7)[0]):
        paths.append(tmp_path / f"scan{k}.ply")
        o3d.io.write_point_cloud(str(paths[-1]), cloud)
    assert main(["-q", "reconstruct", *map(str, paths), "--voxel-size", "0.008", "--out",
                 str(tmp_path / "out"), *flag]) == 0
    assert given == [cameras]
    written = json.loads((tmp_path / "out" / "poses.json").read_text())
    assert written["sensor_frames"] is bool(flag)


@pytest.mark.parametrize("arguments", [
    ["ONE", "--voxel-size", "0.005"],
    ["ONE", "ONE2", "--voxel-size", "-1"],
    ["ONE", "ONE2", "--voxel-size", "0.005", "--workers", "0"],
])
def test_reconstruct_refuses_bad_input_with_exit_2(tmp_path, capsys, arguments):
    arguments = [str(tmp_path / a) if a.startswith("ONE") else a for a in arguments]
    assert main(["reconstruct", *arguments, "--out", str(tmp_path / "out")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 1 and errors[0].startswith("o3d-spectral reconstruct: error: ")
    assert not (tmp_path / "out").exists()


def test_reconstruct_refuses_scans_in_different_units_naming_the_files(tmp_path, capsys):
    cloud = turned_dragon((0,), seed=0)[0][0]
    metres, millimetres = tmp_path / "metres.ply", tmp_path / "millimetres.ply"
    o3d.io.write_point_cloud(str(metres), cloud)
    o3d.io.write_point_cloud(str(millimetres), o3d.geometry.PointCloud(cloud).scale(
        1000.0, center=(0.0, 0.0, 0.0)))
    assert main(["-q", "reconstruct", str(metres), str(millimetres), "--voxel-size", "0.005",
                 "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert f"error: {millimetres} spans" in error and f"and {metres} 0." in error
    assert not (tmp_path / "out").exists()


def test_pairs_of_clouds_that_do_not_exist_are_refused():
    clouds, _ = turned_dragon((0, 24), seed=0)
    record = o3d_spectral.PairwiseRecord(0, 2, np.eye(4), 1.0, 1.0, 0.0, kept=False,
                                         uncertain=True)
    with pytest.raises(ValueError, match=r"records\[0\] pairs clouds 0 and 2"):
        poses_from_pairs(clouds, VOXEL, [record])


def exact_records(confidence_12: float | None) -> tuple[list, list]:
    """Three dragon scans in their scanner frames, and records of their exact relative
    poses: (0, 1) clearly right and confident, (1, 2) as clear but with
    ``confidence_12``, (0, 2) too poor a fit to be kept."""
    angles = (0, 24, 48)
    clouds = [o3d.io.read_point_cloud(str(real.real_dir() / "dragon"
                                          / f"dragonStandRight_{a}.ply")) for a in angles]
    poses = [real.dragon_pose(a) for a in angles]

    def record(i: int, j: int, fit: float, confidence: float | None):
        relative = np.linalg.inv(poses[j]) @ poses[i]
        return o3d_spectral.PairwiseRecord(i, j, relative, fit, fit, 0.1, kept=False,
                                           uncertain=True, confidence=confidence)

    return clouds, [record(0, 1, 0.9, 0.99), record(0, 2, 0.1, 0.99),
                    record(1, 2, 0.9, confidence_12)]


def test_a_cloud_placed_only_through_a_warned_pair_is_reported_doubtful():
    clouds, records = exact_records(0.2)
    result = poses_from_pairs(clouds, VOXEL, records)
    assert result.unconnected == () and result.poses[2] is not None
    assert result.doubtful == (2,)
    warned = [r for r in result.pairs if (r.source, r.target) == (1, 2)][0]
    assert warned.kept and warned.uncertain  # an edge the line process may prune
    confident = [r for r in result.pairs if (r.source, r.target) == (0, 1)][0]
    assert confident.kept and not confident.uncertain


@pytest.mark.parametrize("confidence", [0.99, None])
def test_a_cloud_placed_through_confident_pairs_or_pairs_without_a_confidence_is_not_doubtful(
    confidence,
):
    clouds, records = exact_records(confidence)
    result = poses_from_pairs(clouds, VOXEL, records)
    assert result.unconnected == () and result.doubtful == ()
    assert not [r for r in result.pairs if (r.source, r.target) == (1, 2)][0].uncertain


def test_a_warned_pair_joins_the_tree_only_where_no_confident_pair_does():
    option = o3d_spectral.MultiwayOption()

    def record(fit: float, rival: float, confidence: float | None):
        return o3d_spectral.PairwiseRecord(0, 1, np.eye(4), fit, fit, rival, kept=True,
                                           uncertain=True, confidence=confidence)

    warned, tied, plain = record(0.99, 0.0, 0.3), record(0.4, 0.4, 0.9), record(0.4, 0.4, None)
    assert tree_weight(warned, option) < tree_weight(tied, option) == tree_weight(plain, option)


def test_a_pair_that_a_view_leaves_a_turn_free_joins_the_tree_after_rivalled_pairs():
    """A pair holding a view that leaves a motion free (a mug's body with its handle
    hidden) is right at best up to a turn: it ranks below a pair with a rival as good,
    above a warned one, whatever its fit."""
    option = o3d_spectral.MultiwayOption()

    def record(fit: float, rival: float, confidence: float, determined: bool = True):
        return o3d_spectral.PairwiseRecord(0, 1, np.eye(4), fit, fit, rival, kept=True,
                                           uncertain=True, confidence=confidence,
                                           determined=determined)

    free = record(1.0, 0.0, 0.999, determined=False)
    rivalled, warned = record(0.4, 0.4, 0.9), record(1.0, 0.0, 0.3)
    assert tree_weight(warned, option) < tree_weight(free, option) < tree_weight(rivalled, option)


def test_pairs_are_marked_undetermined_from_a_cloud_that_leaves_a_motion_free():
    """Three clouds, the second a cylinder's side alone (its turn and its slide free):
    both of its pairs are undetermined, the pair of the other two is not."""
    rng = np.random.default_rng(0)
    box = sample_model("cracker_box", 4000)
    side = rng.uniform([0.0, -0.08], [2.0 * np.pi, 0.08], size=(6000, 2))
    tube = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        np.c_[0.05 * np.cos(side[:, 0]), 0.05 * np.sin(side[:, 0]), side[:, 1]]))
    records = [o3d_spectral.PairwiseRecord(i, j, np.eye(4), 0.9, 0.9, 0.0, kept=False,
                                           uncertain=True)
               for i, j in ((0, 1), (0, 2), (1, 2))]
    result = poses_from_pairs([box, tube, o3d.geometry.PointCloud(box)], VOXEL, records)
    assert {(r.source, r.target): r.determined for r in result.pairs} == {
        (0, 1): False, (0, 2): True, (1, 2): False}
