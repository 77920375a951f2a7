"""``o3d-spectral convert``: the real data written as benchmark folders.

``convert ycbv`` run on originals rebuilt from the bundled data (:mod:`tests.real_originals`)
writes the bundled BOP folder again: the same depth image, masks and annotations to the
bit, the same models up to the bundled clouds' float32 rounding. ``convert dragon`` writes
a 3DMatch scene that ``eval --pairs`` reads. Bad input exits 1 with one line naming the
file or folder; bad options exit 2 naming the option.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.cli import main
from tests.real_originals import BOP_YCBV, FRAME, frame_points, write_originals

#: What the BOP folder holds, compared file by file with the bundled one.
IMAGES = ("depth/000001.png", *(f"mask_visib/000001_{k:06d}.png" for k in range(3)))
ANNOTATIONS = ("scene_gt.json", "scene_camera.json", "scene_gt_info.json")


@pytest.fixture(scope="module")
def originals(tmp_path_factory):
    return write_originals(tmp_path_factory.mktemp("originals"))


@pytest.fixture(scope="module")
def converted(originals, tmp_path_factory):
    """``convert ycbv`` of the originals: (its folder, its standard output)."""
    out = tmp_path_factory.mktemp("bop") / "bop_ycbv"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        assert main(["convert", "ycbv", str(originals), str(out)]) == 0
    return out, stdout.getvalue()


def test_ycbv_rewrites_the_bundled_bop_folder(converted):
    out, printed = converted
    lines = printed.splitlines()
    assert [line.split(":")[0] for line in lines[:3]] == [
        "009_gelatin_box obj_000008", "025_mug obj_000014", "061_foam_brick obj_000021"]
    assert "points_to_surface_p95_mm" in lines[0] and "17666 visible pixels" in lines[0]
    assert lines[3] == f"wrote {out}"
    scene, bundled = out / "test" / "000000", BOP_YCBV / "test" / "000000"
    for name in IMAGES:
        mine = np.asarray(o3d.io.read_image(str(scene / name)))
        np.testing.assert_array_equal(mine, np.asarray(o3d.io.read_image(str(bundled / name))))
    for name in ANNOTATIONS[1:]:
        assert json.loads((scene / name).read_text()) == json.loads((bundled / name).read_text())
    # the poses' rotations are projected onto SO(3) by an SVD, whose last bits follow the
    # machine's LAPACK: the same to rounding
    mine, theirs = (json.loads((where / ANNOTATIONS[0]).read_text()) for where in (scene, bundled))
    assert mine.keys() == theirs.keys()
    for image in mine:
        assert [e["obj_id"] for e in mine[image]] == [e["obj_id"] for e in theirs[image]]
        for a, b in zip(mine[image], theirs[image], strict=True):
            np.testing.assert_allclose(a["cam_R_m2c"], b["cam_R_m2c"], rtol=0, atol=1e-14)
            np.testing.assert_allclose(a["cam_t_m2c"], b["cam_t_m2c"], rtol=1e-15, atol=0)
    for folder in ("models", "models_eval"):
        mine = json.loads((out / folder / "models_info.json").read_text())
        theirs = json.loads((BOP_YCBV / folder / "models_info.json").read_text())
        assert mine.keys() == theirs.keys() == {"8", "14", "21"}
        for key in mine:
            assert mine[key].keys() == theirs[key].keys()
            # the bundled clouds are the originals in float32: their diameters agree to
            # 1e-6, a Poisson surface's bounding box to a fraction of a millimetre
            tolerance = 1e-6 if folder == "models_eval" else 1e-2
            np.testing.assert_allclose(mine[key]["diameter"], theirs[key]["diameter"],
                                       rtol=tolerance)
    assert (out / "LICENSE").read_text() == (BOP_YCBV / "LICENSE").read_text()


def test_ycbv_folder_is_read_by_eval_bop(converted):
    from o3d_spectral.harness.bop import BopSet

    crops = BopSet(converted[0])
    assert len(crops) == 3 and crops.model(14).points.shape == (2621, 3)


def test_ycbv_errors_name_the_file(originals, tmp_path, capsys):
    missing = tmp_path / "nowhere"
    assert main(["convert", "ycbv", str(missing), str(tmp_path / "out")]) == 1
    assert capsys.readouterr().err == (
        f"o3d-spectral convert: error: SOURCE {missing}: no such folder\n")

    partial = tmp_path / "partial"
    shutil.copytree(originals / "ycbv", partial / "ycbv")
    (partial / "ycbv" / FRAME / "K.txt").unlink()
    assert main(["convert", "ycbv", str(partial), str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"has no ycbv/{FRAME}/K.txt" in err

    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    assert main(["convert", "ycbv", str(originals), str(foreign)]) == 1
    assert f"OUT {foreign} holds notes.txt" in capsys.readouterr().err
    assert (foreign / "notes.txt").read_text() == "keep me"

    shutil.copyfile(originals / "ycbv" / FRAME / "K.txt", partial / "ycbv" / FRAME / "K.txt")
    off_pixels = frame_points()[:1000] + [0.0005, 0.0, 0.0]  # half a millimetre sideways
    o3d.io.write_point_cloud(str(partial / "ycbv" / FRAME / "scene.ply"),
                             o3d.geometry.PointCloud(o3d.utility.Vector3dVector(off_pixels)))
    assert main(["convert", "ycbv", str(partial), str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert f"{partial / 'ycbv' / FRAME / 'scene.ply'}: the points are not back-projected" in err


def test_dragon_writes_a_3dmatch_scene(tmp_path, capsys):
    from o3d_spectral.harness.pairs import PairSet

    out = tmp_path / "dragon"
    assert main(["convert", "dragon", str(out), "--max-step", "24"]) == 0
    assert capsys.readouterr().out == f"wrote {out}\n"
    assert sorted(p.name for p in out.glob("cloud_bin_*.ply")) == [
        f"cloud_bin_{k}.ply" for k in range(8)]
    pairs = PairSet(out)
    assert len(pairs) == 7  # the neighbouring scans, 24 degrees apart
    assert o3d.io.read_point_cloud(str(out / "cloud_bin_0.ply")).has_normals()


def test_usage_errors_name_the_option(tmp_path, capsys):
    assert main(["convert"]) == 2
    assert "DATASET" in capsys.readouterr().err
    assert main(["convert", "dragon", str(tmp_path / "d"), "--max-step", "10"]) == 2
    assert capsys.readouterr().err == (
        "o3d-spectral convert: error: --max-step must be at least 24 degrees (the scans' "
        "step), got 10\n")
    assert not (tmp_path / "d").exists()
    (tmp_path / "file").write_text("")
    assert main(["convert", "dragon", str(tmp_path / "file")]) == 1
    assert "OUT " in capsys.readouterr().err
