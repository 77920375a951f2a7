"""Suites on disk: determinism, round trip, manifest, pictures and the CLI commands."""

import argparse
import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from o3d_spectral.cli import suite as cli_suite
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.suite import MANIFEST, load_suite, make_suite, save_instance_figure


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def occluded_suite(tmp_path_factory):
    out = tmp_path_factory.mktemp("occluded")
    make_suite("occluded", 3, 7, out, progress=False)
    return out


@pytest.mark.slow
def test_same_seed_gives_identical_files_whatever_the_workers(occluded_suite, tmp_path):
    make_suite("occluded", 3, 7, tmp_path, workers=2, progress=False)
    assert _files(tmp_path) == _files(occluded_suite)


@pytest.mark.slow
def test_another_seed_gives_another_suite(occluded_suite, tmp_path):
    make_suite("occluded", 3, 8, tmp_path, progress=False)
    assert _files(tmp_path)[MANIFEST] != _files(occluded_suite)[MANIFEST]


@pytest.mark.slow
def test_manifest_lists_every_instance(occluded_suite):
    manifest = json.loads((occluded_suite / MANIFEST).read_text())
    assert manifest["format"] == "o3d-spectral-suite"
    assert (manifest["condition"], manifest["n"], manifest["seed"]) == ("occluded", 3, 7)
    assert [e["object"] for e in manifest["instances"]] == model_names()[:3]
    for entry in manifest["instances"]:
        assert (occluded_suite / entry["source"]).is_file()
        assert (occluded_suite / entry["target"]).is_file()
        for key in ("T_gt", "init_angle_deg", "visible_fraction", "occlusion", "view"):
            assert key in entry
        assert abs(entry["occlusion"] - entry["occlusion_requested"]) <= 0.05


@pytest.mark.slow
def test_loaded_instances_match_the_generated_ones(occluded_suite):
    from o3d_spectral.synthetic.scenes import make_instance
    from o3d_spectral.synthetic.suite import instance_rng

    suite = load_suite(occluded_suite)
    assert len(suite) == 3 and suite.condition == "occluded"
    for index, loaded in enumerate(suite):
        fresh = make_instance("occluded", loaded.object, rng=instance_rng(7, index))
        assert_allclose(loaded.T_gt, fresh.T_gt)
        assert_allclose(
            np.asarray(loaded.target.points), np.asarray(fresh.target.points), atol=1e-6
        )
        assert_allclose(
            np.asarray(loaded.source.normals), np.asarray(fresh.source.normals), atol=1e-6
        )
        assert np.array_equal(loaded.target_labels, fresh.target_labels)
        assert loaded.metadata == json.loads(json.dumps(fresh.metadata))
        assert loaded.symmetry.discrete.shape[1:] == (4, 4)


def test_figure_is_written(occluded_suite, tmp_path):
    path = save_instance_figure(load_suite(occluded_suite)[0], tmp_path / "a.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_make_suite_rejects_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="condition"):
        make_suite("foggy", 1, 0, tmp_path)
    with pytest.raises(ValueError, match="n must"):
        make_suite("full", 0, 0, tmp_path)
    with pytest.raises(ValueError, match="workers"):
        make_suite("full", 1, 0, tmp_path, workers=0)
    with pytest.raises(FileNotFoundError, match=MANIFEST):
        load_suite(tmp_path)


def _run(argv):
    parser = argparse.ArgumentParser()
    cli_suite.add_parser(parser.add_subparsers())
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.mark.slow
def test_cli_makes_and_shows_a_suite(tmp_path):
    out = tmp_path / "full"
    argv = ["make-suite", "full", "--n", "2", "--seed", "1", "--out", str(out), "--quiet"]
    assert _run([*argv, "--angle-range", "10", "20"]) == 0
    suite = load_suite(out)
    assert all(10 <= inst.metadata["init_angle_deg"] <= 20 for inst in suite)
    assert _run(["show-suite", str(out), "--index", "1", "--out", str(tmp_path / "f.png")]) == 0
    assert (tmp_path / "f.png").is_file()
    with pytest.raises(ValueError, match="index"):
        _run(["show-suite", str(out), "--index", "5", "--out", str(tmp_path / "g.png")])
