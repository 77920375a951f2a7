"""Scene generator: ground truth, occlusion, clutter placement, rotation law, seeding."""

import numpy as np
import open3d as o3d
import pytest
from numpy.testing import assert_allclose
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from o3d_spectral.synthetic.camera import scan_meshes
from o3d_spectral.synthetic.instance import CONDITIONS, SceneOptions
from o3d_spectral.synthetic.models import load_model
from o3d_spectral.synthetic.sampling import model_cloud
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise
from o3d_spectral.synthetic.tabletop import place_on_table


def _distance_to_mesh(mesh, pose, points):
    """Distance (m) of points to ``mesh`` placed by the 4x4 ``pose``."""
    moved = o3d.geometry.TriangleMesh(mesh).transform(pose)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(moved))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def _noise_bound(points, options):
    """Per-point bound on the sensor error: 5 sigma plus one quantisation step (m)."""
    if not len(points):
        return 0.0
    z = np.abs(points[:, 2])
    step = z**2 * options.noise.disparity_step / (options.intrinsics.fx * options.noise.baseline)
    return 5 * options.noise.sigma(z) + step + 1e-4


@pytest.mark.slow
@pytest.mark.parametrize("condition", CONDITIONS)
@pytest.mark.parametrize("name", ["mug", "cracker_box"])
def test_ground_truth_puts_the_source_on_the_target_object(condition, name):
    options = SceneOptions()
    inst = make_instance(condition, name, rng=np.random.default_rng(11), options=options)
    mesh = load_model(name)
    source = np.asarray(inst.source.points)
    target = np.asarray(inst.target.points)[inst.target_labels == 0]
    assert len(target) > 100
    # The source is the model sampled on the mesh, presented by source_from_model.
    assert _distance_to_mesh(mesh, inst.source_from_model, source).max() < 1e-6
    # Target object points lie on the mesh placed by T_gt @ source_from_model, within noise.
    target_from_model = inst.T_gt @ inst.source_from_model
    assert_allclose(target_from_model, inst.metadata["object_poses"][0], atol=1e-9)
    distance = _distance_to_mesh(mesh, target_from_model, target)
    if condition == "full":
        assert np.all(distance < 5 * options.full_noise_sigma)
    else:
        assert np.all(distance < _noise_bound(target, options))
    # And the moved source covers them: nearest source point within sampling + noise.
    moved = source @ inst.T_gt[:3, :3].T + inst.T_gt[:3, 3]
    assert np.median(cKDTree(moved).query(target)[0]) < 0.004


@pytest.mark.slow
@pytest.mark.parametrize("condition", CONDITIONS)
def test_same_seed_same_instance(condition):
    a = make_instance(condition, "banana", rng=np.random.default_rng(5))
    b = make_instance(condition, "banana", rng=np.random.default_rng(5))
    assert np.array_equal(np.asarray(a.target.points), np.asarray(b.target.points))
    assert np.array_equal(np.asarray(a.source.points), np.asarray(b.source.points))
    assert np.array_equal(a.T_gt, b.T_gt)
    assert a.metadata == b.metadata


@pytest.mark.slow
@pytest.mark.parametrize("requested", [0.2, 0.45, 0.7])
def test_measured_occlusion_matches_the_request(requested):
    options = SceneOptions()
    inst = make_instance(
        "occluded", "power_drill", rng=np.random.default_rng(3), occlusion=requested
    )
    meta = inst.metadata
    assert abs(meta["occlusion"] - requested) <= 0.05
    assert meta["occlusion_requested"] == requested
    # Independent check on the delivered cloud: compare with an unoccluded scan of the same view.
    pose = np.array(meta["view"]["world_from_camera"])
    alone = scan_meshes(
        [load_model("power_drill")], options.intrinsics, pose, rng=np.random.default_rng(0)
    )
    assert abs(1 - len(inst.target.points) / len(alone.points) - requested) <= 0.05


@pytest.mark.slow
def test_partial_view_sees_the_whole_object_at_working_distance():
    options = SceneOptions()
    for seed in range(3):
        inst = make_instance("partial", "power_drill", rng=np.random.default_rng(seed))
        pose = np.array(inst.metadata["object_poses"][0])
        vertices = np.asarray(load_model("power_drill").vertices) @ pose[:3, :3].T + pose[:3, 3]
        uv = options.intrinsics.project(vertices)
        assert np.all((uv >= 0) & (uv <= [639, 479]))
        assert 0.4 <= inst.metadata["view"]["camera_distance_m"] <= 1.0
        assert np.all(np.asarray(inst.target.points)[:, 2] > options.noise.min_depth)
        assert 0.1 < inst.metadata["visible_fraction"] < 0.9


@pytest.mark.slow
def test_cluttered_scene_has_the_table_and_a_visible_object():
    inst = make_instance("cluttered", "mustard_bottle", rng=np.random.default_rng(8))
    meta = inst.metadata
    assert 3 <= len(meta["scene_objects"]) <= 8
    assert meta["scene_objects"][0] == "mustard_bottle"
    assert set(np.unique(inst.target_labels)) == {-1, *range(len(meta["scene_objects"]))}
    assert 1 - meta["occlusion"] >= 0.3
    normals, points = np.asarray(inst.target.normals), np.asarray(inst.target.points)
    assert np.all(np.einsum("ij,ij->i", normals, points) < 0)


@pytest.mark.slow
def test_objects_on_the_table_rest_on_it_without_overlap():
    names = ["power_drill", "bowl", "mug", "cracker_box", "banana", "scissors", "foam_brick"]
    placed, poses = place_on_table(names, np.random.default_rng(4))
    assert len(placed) >= 3
    clouds = []
    for name, pose in zip(placed, poses, strict=True):
        vertices = np.asarray(load_model(name).vertices) @ pose[:3, :3].T + pose[:3, 3]
        assert_allclose(vertices[:, 2].min(), 0.0, atol=1e-9)
        clouds.append(vertices)
    for i in range(len(clouds)):
        for j in range(i + 1, len(clouds)):
            gap = cKDTree(clouds[i][:, :2]).query(clouds[j][:, :2])[0].min()
            assert gap > 0.001, (placed[i], placed[j])


def test_angle_range_and_offset_bound_are_respected():
    lo, hi = np.deg2rad(30), np.deg2rad(40)
    options = SceneOptions(angle_range=(lo, hi), max_offset=0.05)
    for seed in range(5):
        inst = make_instance("full", "mug", rng=np.random.default_rng(seed), options=options)
        angle = Rotation.from_matrix(inst.T_gt[:3, :3]).magnitude()
        assert lo <= angle <= hi
        assert_allclose(np.rad2deg(angle), inst.metadata["init_angle_deg"])
        source = np.asarray(inst.source.points)
        moved = source @ inst.T_gt[:3, :3].T + inst.T_gt[:3, 3]
        offset = np.linalg.norm(moved.mean(axis=0) - source.mean(axis=0))
        assert_allclose(offset, inst.metadata["init_offset_m"], atol=1e-9)
        assert offset <= 0.05


def test_default_rotation_law_is_uniform_on_so3():
    # Haar measure: the angle has density (1 - cos a) / pi, so its mean is pi/2 + 2/pi.
    angles = [
        make_instance("full", "bowl", rng=np.random.default_rng(s)).metadata["init_angle_deg"]
        for s in range(60)
    ]
    assert abs(np.mean(np.deg2rad(angles)) - (np.pi / 2 + 2 / np.pi)) < 0.25


def test_source_normals_point_outward():
    points, normals = model_cloud("cracker_box", 3000)
    assert np.mean(np.einsum("ij,ij->i", points - points.mean(axis=0), normals) > 0) > 0.95


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"angle_range": (1.0, 0.5)}, "angle_range"),
        ({"max_offset": -1.0}, "max_offset"),
        ({"occlusion_range": (0.2, 1.2)}, "occlusion_range"),
        ({"source_points": 10}, "source_points"),
    ],
)
def test_options_reject_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SceneOptions(**kwargs)


def test_make_instance_rejects_bad_arguments():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="condition"):
        make_instance("foggy", "mug", rng=rng)
    with pytest.raises(ValueError, match="unknown model"):
        make_instance("full", "teapot", rng=rng)
    with pytest.raises(ValueError, match="occlusion"):
        make_instance("partial", "mug", rng=rng, occlusion=0.3)


def test_noise_free_options_give_exact_scans():
    options = SceneOptions(noise=DepthNoise.noiseless(), intrinsics=CameraIntrinsics())
    inst = make_instance("partial", "gelatin_box", rng=np.random.default_rng(2), options=options)
    target = np.asarray(inst.target.points)
    distance = _distance_to_mesh(
        load_model("gelatin_box"), inst.T_gt @ inst.source_from_model, target
    )
    assert distance.max() < 1e-5
