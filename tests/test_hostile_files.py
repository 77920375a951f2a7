"""Issue 19, files: truncated, corrupt and crafted cloud files, manifests and run folders.

Each refuses with one clear error naming the file (and the key), never a pose or a row
computed from garbage.
"""

import json
import logging
import shutil

import numpy as np
import open3d as o3d
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from o3d_spectral.cli import main
from o3d_spectral.io.files import atomic_write_text, check_cloud_file
from o3d_spectral.synthetic.suite import MANIFEST, load_suite, make_suite
from tests.conftest import sample_model

VOXEL = ["--voxel-size", "0.02"]


@pytest.fixture(scope="module")
def clouds(tmp_path_factory):
    """A good binary PLY and PCD of a model, and damaged copies."""
    folder = tmp_path_factory.mktemp("clouds")
    cloud = sample_model("mustard_bottle", 3000)
    o3d.io.write_point_cloud(str(folder / "good.ply"), cloud)
    o3d.io.write_point_cloud(str(folder / "good.pcd"), cloud)
    o3d.io.write_point_cloud(str(folder / "ascii.ply"), cloud, write_ascii=True)
    data = (folder / "good.ply").read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    (folder / "truncated.ply").write_bytes(data[: end + (len(data) - end) // 2])
    (folder / "huge.ply").write_bytes(
        data[:end].replace(b"element vertex 3000", b"element vertex 1000000000") + data[end:]
    )
    (folder / "headless.ply").write_bytes(data[:end - 5])
    (folder / "garbage.ply").write_bytes(b"\x00\x17 not a ply at all" * 50)
    text = (folder / "ascii.ply").read_text().splitlines(keepends=True)
    (folder / "short_ascii.ply").write_text("".join(text[: len(text) // 2]))
    pcd = (folder / "good.pcd").read_bytes()
    (folder / "truncated.pcd").write_bytes(pcd[: len(pcd) // 2])
    points = np.asarray(cloud.points).copy()
    points[::100] = np.nan
    points[1] = np.inf
    o3d.io.write_point_cloud(str(folder / "nan.ply"), o3d.geometry.PointCloud(
        o3d.utility.Vector3dVector(points)))
    return folder


@pytest.mark.parametrize("name", ["truncated.ply", "huge.ply", "headless.ply", "garbage.ply",
                                  "short_ascii.ply", "truncated.pcd", "nan.ply"])
def test_register_refuses_a_damaged_file_by_name(clouds, name, capsys):
    """Exit 1, one error line naming the file, and no pose on stdout (a truncated PLY
    used to give Open3D's uninitialised points and, sometimes, exit 0 with a pose)."""
    bad = clouds / name
    for args in ([str(bad), str(clouds / "good.ply")], [str(clouds / "good.ply"), str(bad)]):
        assert main(["register", *args, *VOXEL]) == 1
        out, err = capsys.readouterr()
        assert out == ""
        assert err.count("\n") == 1 and str(bad) in err, err


def test_header_claiming_a_billion_vertices_is_refused_before_reading(clouds):
    with pytest.raises(ValueError, match="1000000000 vertices"):
        check_cloud_file(clouds / "huge.ply")


def test_good_files_pass_the_checks(clouds):
    for name in ("good.ply", "good.pcd", "ascii.ply"):
        check_cloud_file(clouds / name)


def test_drop_nan_registers_the_finite_points_with_a_warning(clouds, capsys, caplog):
    args = ["register", str(clouds / "nan.ply"), str(clouds / "good.ply"), *VOXEL, "--json"]
    with caplog.at_level(logging.WARNING, logger="o3d_spectral"):
        assert main([*args, "--drop-nan"]) == 0
    out, err = capsys.readouterr()
    result = json.loads(out)
    assert np.all(np.isfinite(result["transformation"]))
    assert "nan.ply: dropped 31 of 3000 points" in err


def test_init_file_errors_name_the_file(clouds, tmp_path, capsys):
    bad = tmp_path / "init.txt"
    for text in ("1 2 3\n", "a b c d\n" * 4, "nan 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"):
        bad.write_text(text)
        args = ["register", str(clouds / "good.ply"), str(clouds / "good.ply"), *VOXEL]
        assert main([*args, "--init", str(bad)]) == 1
        assert str(bad) in capsys.readouterr().err


# ---------------------------------------------------------------------- suites, manifests


@pytest.fixture(scope="module")
def suite_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("suites") / "full"
    make_suite("full", 2, 0, out, progress=False)
    return out


def _copy(suite_dir, tmp_path, edit=None):
    folder = tmp_path / "suite"
    shutil.copytree(suite_dir, folder)
    if edit is not None:
        manifest = json.loads((folder / MANIFEST).read_text())
        manifest = edit(manifest)
        (folder / MANIFEST).write_text(json.dumps(manifest))
    return folder


def _drop(key):
    def edit(m):
        del m[key]
        return m
    return edit


def _set(path, value):
    def edit(m):
        target = m
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
        return m
    return edit


@pytest.mark.parametrize("edit, key", [
    (lambda m: m["instances"], "JSON object"),
    (_drop("instances"), "instances"),
    (_drop("seed"), "seed"),
    (_set(["instances"], {"0": 1}), "instances"),
    (_set(["seed"], "0"), "seed"),
    (_set(["condition"], "sideways"), "condition"),
    (_set(["options"], []), "options"),
    (_set(["options", "intrinsics"], None), "options"),
    (_set(["instances", 0], []), "instances[0]"),
    (_set(["instances", 1, "T_gt"], [[1, 0], [0, 1]]), "instances[1].T_gt"),
    (_set(["instances", 1, "T_gt"], [[float("nan")] * 4] * 4), "instances[1].T_gt"),
    (_set(["instances", 0, "T_gt"], np.diag([2.0, 1, 1, 1]).tolist()), "instances[0].T_gt"),
    (_set(["instances", 0, "source"], 7), "instances[0].source"),
    (_set(["instances", 0, "source"], "/etc/passwd"), "instances[0].source"),
    (_set(["instances", 0, "target"], "../full/0000_target.ply"), "instances[0].target"),
])
def test_bad_manifest_is_refused_naming_file_and_key(suite_dir, tmp_path, edit, key):
    folder = _copy(suite_dir, tmp_path, edit)
    with pytest.raises(ValueError) as error:
        load_suite(folder)
    assert str(folder / MANIFEST) in str(error.value) and key in str(error.value)


def test_manifest_that_is_not_json_is_refused(suite_dir, tmp_path):
    folder = _copy(suite_dir, tmp_path)
    (folder / MANIFEST).write_text('{"format": "o3d-spectral-suite", "vers')
    with pytest.raises(ValueError, match="not a JSON manifest"):
        load_suite(folder)


def test_instance_file_linked_outside_the_suite_is_refused(suite_dir, tmp_path):
    folder = _copy(suite_dir, tmp_path)
    outside = tmp_path / "outside.ply"
    shutil.copy(folder / "0000_source.ply", outside)
    (folder / "0000_source.ply").unlink()
    (folder / "0000_source.ply").symlink_to(outside)
    suite = load_suite(folder)
    with pytest.raises(ValueError, match="inside the suite folder"):
        suite[0]
    suite[1]  # the others still load


@pytest.mark.parametrize("damage", ["missing", "truncated", "empty"])
def test_missing_or_corrupt_instance_file_is_named(suite_dir, tmp_path, damage):
    folder = _copy(suite_dir, tmp_path)
    path = folder / "0001_target.ply"
    if damage == "missing":
        path.unlink()
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[:-5000])
    else:
        path.write_bytes(b"")
    suite = load_suite(folder)
    suite[0]
    with pytest.raises((ValueError, FileNotFoundError), match=str(path)):
        suite[1]


def _manifest_values():
    scalar = st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(),
                       st.text(max_size=4))
    return st.recursive(scalar, lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=3)),
        max_leaves=8)


@pytest.mark.slow
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_manifest_loads_or_is_refused_by_name(suite_dir, tmp_path_factory, data):
    """A manifest with one key (top level or of an instance) replaced or dropped: the
    suite loads and its instances read, or a ValueError/FileNotFoundError names the file."""
    manifest = json.loads((suite_dir / MANIFEST).read_text())
    where = data.draw(st.sampled_from(["top", "instance", "whole"]))
    if where == "whole":
        manifest = data.draw(_manifest_values())
    else:
        target = manifest if where == "top" else manifest["instances"][data.draw(
            st.integers(0, 1))]
        key = data.draw(st.sampled_from(sorted(target)))
        if data.draw(st.booleans()):
            del target[key]
        else:
            target[key] = data.draw(_manifest_values())
    folder = tmp_path_factory.mktemp("crafted")
    for name in ("0000_source.ply", "0000_target.ply", "0001_source.ply", "0001_target.ply"):
        shutil.copy(suite_dir / name, folder / name)
    (folder / MANIFEST).write_text(json.dumps(manifest))
    try:
        suite = load_suite(folder)
        for k in range(len(suite)):
            suite[k]
    except (ValueError, FileNotFoundError) as error:
        assert str(folder) in str(error) or str(suite_dir) in str(error), error


def test_atomic_write_replaces_whole_or_not_at_all(tmp_path):
    path = tmp_path / "config.json"
    atomic_write_text(path, "old\n")

    with pytest.raises(TypeError):
        atomic_write_text(path, 12)  # fails while writing the temporary file
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["config.json"]  # no temporary left


# ---------------------------------------------------------------------- eval and report


def _harness():
    pytest.importorskip("pandas", reason="the harness extra is not installed")
    pytest.importorskip("matplotlib", reason="the harness extra is not installed")
    from o3d_spectral.harness import load_results, run_eval
    from o3d_spectral.harness.report import make_report

    return run_eval, load_results, make_report


def _records():
    from o3d_spectral.harness.records import read_config, result_files

    return read_config, result_files


def _lines(out):
    """Every results line of the run folder ``out``, over the sessions' files."""
    _, result_files = _records()
    return [line for file in result_files(out) for line in file.read_text().splitlines()]


@pytest.mark.slow
def test_eval_stops_on_a_missing_instance_file_naming_it(suite_dir, tmp_path):
    """Not recorded as the method's failure: the eval stops and says which file."""
    run_eval, load_results, _ = _harness()
    folder = _copy(suite_dir, tmp_path)
    (folder / "0001_source.ply").unlink()
    out = tmp_path / "run"
    with pytest.raises(FileNotFoundError, match=str(folder / "0001_source.ply")):
        run_eval([folder], out, methods=["icp_point_to_point"], progress=False)
    assert all(json.loads(row)["index"] == 0 for row in _lines(out))
    read_config, _ = _records()
    assert read_config(out)["sessions"][-1]["complete"] is False


@pytest.mark.slow
@pytest.mark.parametrize("layout", ["sessions", "legacy"])
def test_resume_reruns_rows_that_failed_for_input_reasons(suite_dir, tmp_path, layout):
    """Rows an older version recorded for an empty (missing) instance file are run again,
    into a new session's file; the new row wins. Method failures are kept."""
    run_eval, load_results, _ = _harness()
    _, result_files = _records()
    out = tmp_path / "run"
    run_eval([suite_dir], out, methods=["icp_point_to_point"], progress=False)
    first = load_results(out)
    (file,) = result_files(out)
    rows = [json.loads(line) for line in file.read_text().splitlines()]
    for row, error in zip(rows, ["ValueError: source is empty", "RuntimeError: method"],
                          strict=True):
        for key in [k for k in row if k not in _IDENTITY]:
            row.pop(key)
        row |= {"error": error, "success": False}
    file.write_text("".join(json.dumps(r) + "\n" for r in rows))
    if layout == "legacy":  # an older run folder: one results.jsonl
        file.rename(out / "results.jsonl")
    run_eval([suite_dir], out, methods=["icp_point_to_point"], progress=False)
    again = load_results(out)
    assert len(result_files(out)) == 2
    assert len(_lines(out)) == 3  # one rerun appended, to the new session's file
    assert again.loc[0, "error"] is None or again["error"].isna()[0]
    assert again.loc[0, "rotation_error_sym_deg"] == first.loc[0, "rotation_error_sym_deg"]
    assert again.loc[1, "error"] == "RuntimeError: method"


_IDENTITY = {"suite", "index", "method", "condition", "object", "init_angle_deg",
             "init_offset_m", "visible_fraction", "occlusion", "seed", "time_s"}


def test_report_on_a_run_whose_rows_all_failed(tmp_path):
    _, _, make_report = _harness()
    rows = [
        {"suite": "full", "index": i, "method": m, "condition": "full", "object": "mug",
         "init_angle_deg": 30.0, "init_offset_m": 0.05, "visible_fraction": 1.0,
         "occlusion": 0.0, "seed": 1, "time_s": 0.1, "error": "RuntimeError: x",
         "success": False}
        for i in range(2) for m in ("spectral", "icp_point_to_point")
    ]
    (tmp_path / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    written = make_report(tmp_path, tmp_path / "report")
    summary = written["summary.md"].read_text()
    assert "| C-1 (full) | spectral | 2 | 0.0 |" in summary


@pytest.mark.parametrize("text, message", [
    ('{"suite": "full"}\n', "line 1: not a results row"),
    ('[1, 2]\n', "line 1: not a results row"),
    ('{"suite": "full", "index": 0, "method": "x"}\n%%%\n', "line 2: not a results row"),
])
def test_corrupt_results_file_is_named(tmp_path, text, message):
    _, load_results, _ = _harness()
    (tmp_path / "results.jsonl").write_text(text)
    with pytest.raises(ValueError, match=message):
        load_results(tmp_path)


def test_rows_are_read_as_json_reads_them(tmp_path):
    """Whichever parser reads a row (orjson refuses NaN, Infinity and integers beyond 64
    bits, which json writes), the values are json's."""
    _, load_results, _ = _harness()
    rows = [
        {"suite": "full", "index": 0, "method": "x", "fitness": float("nan"), "seed": 2**70},
        {"suite": "full", "index": 1, "method": "x", "fitness": float("inf"), "seed": 1},
        {"suite": "full", "index": 2, "method": "x", "fitness": 0.1 + 0.2, "seed": 2},
    ]
    (tmp_path / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    frame = load_results(tmp_path)
    assert np.isnan(frame.loc[0, "fitness"]) and frame.loc[1, "fitness"] == float("inf")
    assert frame.loc[2, "fitness"] == 0.1 + 0.2
    assert list(frame["seed"]) == [2**70, 1, 2]


def test_corrupt_session_files_are_named(tmp_path):
    _, load_results, _ = _harness()
    read_config, _ = _records()
    row = {"suite": "full", "index": 0, "method": "x"}
    (tmp_path / "results").mkdir()
    results = tmp_path / "results" / "20260101T000000000000-a.jsonl"
    results.write_text(json.dumps(row) + "\n%%%\n" + '{"suite": "full", "ind')
    with pytest.raises(ValueError, match=f"{results}, line 2: not a results row"):
        load_results(tmp_path)
    results.write_text(json.dumps(row) + "\n" + '{"suite": "full", "ind')  # still writing
    assert len(load_results(tmp_path)) == 1
    (tmp_path / "sessions").mkdir()
    session = tmp_path / "sessions" / "20260101T000000000000-a.json"
    for text, message in [("{", "not valid JSON"), ("[]", "not a session's file")]:
        session.write_text(text)
        with pytest.raises(ValueError, match=f"{session} is {message}"):
            read_config(tmp_path)
    session.unlink()
    (tmp_path / "config.json").write_text('{"suites": 1}')
    with pytest.raises(ValueError, match="config.json is not a run's config"):
        read_config(tmp_path)


def test_files_are_created_with_the_callers_umask(tmp_path):
    import os

    from o3d_spectral.io.files import atomic_write_text

    saved = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(saved)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o640
