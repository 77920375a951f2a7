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
