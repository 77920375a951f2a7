"""Mutations of a BOP dataset's files and of a gt.log: each is refused by an error that
names the file and the field (or line), never a bare numpy or Python error."""

from __future__ import annotations

import json
import shutil

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.harness import bop_write, pose_metrics
from o3d_spectral.harness.bop import BopSet
from o3d_spectral.harness.pairs import PairSet, write_log
from o3d_spectral.spectra import so3

K = np.array([[150.0, 0.0, 80.0], [0.0, 150.0, 60.0], [0.0, 0.0, 1.0]])
POSE = np.eye(4)
POSE[:3, :3] = so3.exp(np.deg2rad(35.0) * np.array([0.6, 0.8, 0.0]))
POSE[:3, 3] = [0.02, -0.01, 0.5]
SCENE = "test/000003"


@pytest.fixture(scope="module")
def bop_original(tmp_path_factory):
    """A one-image BOP dataset: a box (object 5) before a wall."""
    root = tmp_path_factory.mktemp("bop") / "boxes"
    mesh = o3d.geometry.TriangleMesh.create_box(0.06, 0.04, 0.02)
    mesh.translate((-0.03, -0.02, -0.01))
    mesh.compute_vertex_normals()
    bop_write.write_model(root, 5, mesh)
    rendered = pose_metrics.render_depth(mesh, POSE, K, (120, 160))
    depth = np.where(rendered > 0, rendered, 0.7)
    bop_write.write_image(root / SCENE, 7, depth, K, [(5, POSE, rendered > 0, 1.0)])
    return root


def _edit_json(name):
    def edit(change):
        def apply(root):
            path = root / name
            document = json.loads(path.read_text())
            change(document)
            path.write_text(json.dumps(document))
        return apply
    return edit


gt, camera = _edit_json(f"{SCENE}/scene_gt.json"), _edit_json(f"{SCENE}/scene_camera.json")
info, models = _edit_json(f"{SCENE}/scene_gt_info.json"), _edit_json("models/models_info.json")


def _set(key, value):
    return lambda document: document["7"][0].__setitem__(key, value)


def _scaled(document):
    document["7"][0]["cam_R_m2c"] = [2 * v for v in document["7"][0]["cam_R_m2c"]]


def _reflected(document):
    document["7"][0]["cam_R_m2c"] = [-v for v in document["7"][0]["cam_R_m2c"]]


def _targets(value):
    return lambda root: (root / "test_targets_bop19.json").write_text(json.dumps(value))


def _corrupt_depth(root):
    (root / SCENE / "depth" / "000007.png").write_bytes(b"\x89PNG\r\n\x1a\nnot an image")


BOP_MUTATIONS = {
    "R scaled": (gt(_scaled), "scene_gt.json.*image 7, annotation 0.*cam_R_m2c"),
    "R zeros": (gt(_set("cam_R_m2c", [0] * 9)), "scene_gt.json.*cam_R_m2c"),
    "R reflection": (gt(_reflected), "scene_gt.json.*cam_R_m2c"),
    "R six numbers": (gt(_set("cam_R_m2c", [1, 0, 0, 0, 1, 0])), "scene_gt.json.*cam_R_m2c"),
    "t NaN": (gt(_set("cam_t_m2c", [float("nan"), 0, 500])), "scene_gt.json.*cam_t_m2c"),
    "t huge": (gt(_set("cam_t_m2c", [1e308, 0, 500])), "scene_gt.json.*cam_t_m2c"),
    "obj_id missing": (gt(lambda d: d["7"][0].pop("obj_id")), "scene_gt.json.*obj_id"),
    "obj_id a path": (gt(_set("obj_id", "../../etc")), "scene_gt.json.*obj_id"),
    "image key": (gt(lambda d: d.__setitem__("abc", d.pop("7"))), "scene_gt.json.*'abc'"),
    "K zeros": (camera(lambda d: d["7"].__setitem__("cam_K", [0] * 9)),
                "scene_camera.json.*image 7.*cam_K"),
    "K six numbers": (camera(lambda d: d["7"].__setitem__("cam_K", [1] * 6)),
                      "scene_camera.json.*image 7.*cam_K"),
    "image not in camera": (camera(lambda d: d.__setitem__("8", d.pop("7"))),
                            "scene_camera.json.*image 7"),
    "depth_scale a string": (camera(lambda d: d["7"].__setitem__("depth_scale", "x")),
                             "scene_camera.json.*depth_scale"),
    "info shorter": (info(lambda d: d.__setitem__("7", [])), "scene_gt_info.json.*image 7"),
    "visib_fract a string": (info(lambda d: d["7"][0].__setitem__("visib_fract", "most")),
                             "scene_gt_info.json.*visib_fract"),
    "diameter a string": (models(lambda d: d["5"].__setitem__("diameter", "big")),
                          "models_info.json.*object 5.*diameter"),
    "targets an object": (_targets({"scene_id": 3}), "test_targets_bop19.json"),
    "target's im_id a string": (_targets([{"scene_id": 3, "im_id": "7", "obj_id": 5}]),
                                "test_targets_bop19.json.*target 0.*im_id"),
    "corrupt depth": (_corrupt_depth, "depth.*000007.png"),
}


def test_the_bop_original_reads(bop_original):
    assert len(BopSet(bop_original, "test", "crop")[0].target.points) > 3


@pytest.mark.parametrize("mutation", BOP_MUTATIONS)
def test_a_mutated_bop_file_is_refused_by_name(bop_original, tmp_path, mutation):
    root = tmp_path / "boxes"
    shutil.copytree(bop_original, root)
    mutate, match = BOP_MUTATIONS[mutation]
    mutate(root)
    with pytest.raises((ValueError, FileNotFoundError), match=match):
        BopSet(root, "test", "crop")[0]


@pytest.fixture(scope="module")
def pairs_original(tmp_path_factory):
    scene = tmp_path_factory.mktemp("pairs") / "scene"
    scene.mkdir()
    cloud = o3d.geometry.TriangleMesh.create_box(0.1, 0.2, 0.3).sample_points_uniformly(500)
    for k in (0, 1):
        o3d.io.write_point_cloud(str(scene / f"cloud_bin_{k}.ply"), cloud)
    write_log(scene / "gt.log", {(0, 1): POSE}, 2)
    write_log(scene / "gt.info", {(0, 1): np.eye(6)}, 2)
    return scene


def _matrix_edit(change):
    def apply(scene):
        lines = (scene / "gt.log").read_text().splitlines()
        rows = [line.split() for line in lines[1:]]
        change(rows)
        (scene / "gt.log").write_text("\n".join([lines[0], *("\t".join(r) for r in rows)]))
    return apply


def _link_fragment(scene):
    outside = scene.parent / "elsewhere.ply"
    (scene / "cloud_bin_1.ply").rename(outside)
    (scene / "cloud_bin_1.ply").symlink_to(outside)


def _link_log(scene):
    secret = scene.parent / "secret.txt"
    secret.write_text("0 1 2\nsecret-token\n")
    (scene / "gt.log").unlink()
    (scene / "gt.log").symlink_to(secret)


LOG_MUTATIONS = {
    "NaN": (_matrix_edit(lambda r: r[0].__setitem__(0, "nan")), "gt.log.*pair 0 1.*transformation"),
    "inf translation": (_matrix_edit(lambda r: r[0].__setitem__(3, "inf")), "gt.log.*pair 0 1"),
    "scaled rotation": (_matrix_edit(lambda r: r.__setitem__(
        slice(0, 3), [[str(2 * float(v)) for v in row[:3]] + row[3:] for row in r[:3]])),
        "gt.log.*pair 0 1.*rigid"),
    "last row ones": (_matrix_edit(lambda r: r.__setitem__(3, ["1"] * 4)), "gt.log.*rigid"),
    "not UTF-8": (lambda s: (s / "gt.log").write_bytes(b"0 1 2\n\xff\xfe\n"), "gt.log.*UTF-8"),
    "fragment linked out": (_link_fragment, "cloud_bin_1.ply links out"),
    "gt.log linked out": (_link_log, "gt.log links out"),
}


@pytest.mark.parametrize("mutation", LOG_MUTATIONS)
def test_a_mutated_gt_log_is_refused_by_name(pairs_original, tmp_path, mutation):
    scene = tmp_path / "scene"
    shutil.copytree(pairs_original, scene)
    assert len(PairSet(scene)) == 1
    mutate, match = LOG_MUTATIONS[mutation]
    mutate(scene)
    with pytest.raises(ValueError, match=match) as error:
        PairSet(scene)[0]
    assert "secret-token" not in str(error.value)
