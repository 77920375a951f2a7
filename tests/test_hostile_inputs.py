"""Issue 19, the library's calls under hostile input: property-based tests over clouds and
options, and the defects whose fix was in the core numerical modules (thread-safe FFT
plans, planes and far-off clouds without normals, settings of the wrong class, grids
beyond the memory budget).

The contract: a call either raises ``ValueError``/``TypeError`` whose message names the
argument, or returns a finite rigid transformation; it never modifies its inputs, and the
same call gives the same result twice.
"""

import dataclasses
import decimal
import fractions
import math
import numbers
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import open3d as o3d
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

import o3d_spectral
from o3d_spectral import (
    CloudOption,
    GlobalSearchOption,
    RefinementOption,
    SpectralConvergenceCriteria,
    SpectralRegistrationOption,
)
from o3d_spectral.common.checks import check_transformation
from tests.conftest import sample_model

OPTION_CLASSES = [SpectralRegistrationOption, CloudOption, GlobalSearchOption,
                  RefinementOption, SpectralConvergenceCriteria]
VOXEL = 0.02


def assert_rigid(T):
    T = np.asarray(T)
    assert T.shape == (4, 4) and np.all(np.isfinite(T))
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert abs(np.linalg.det(R) - 1.0) < 1e-9
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])


# ---------------------------------------------------------------------------- options

_ANY_VALUE = st.one_of(
    st.none(), st.booleans(), st.integers(-10**12, 10**12), st.floats(),
    st.text(max_size=5), st.sampled_from(["False", "auto", "trilinear", "1.0", "nan"]),
    st.lists(st.floats(), max_size=4), st.tuples(st.floats(), st.floats(), st.floats()),
    st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    st.builds(np.float64, st.floats()), st.builds(np.int64, st.integers(-10**6, 10**6)),
    st.just(object()), st.just(complex(1, 1)),
)


def _sane(value) -> bool:
    """What an accepted field may hold: None, a bool, a finite number, a str, or a tuple
    of those."""
    if value is None or isinstance(value, bool | np.bool_ | str):
        return True
    if isinstance(value, tuple):
        return all(_sane(v) for v in value)
    return isinstance(value, int | float | np.integer | np.floating) and math.isfinite(value)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_any_option_value_is_accepted_sanely_or_refused_by_name(data):
    cls = data.draw(st.sampled_from(OPTION_CLASSES))
    field = data.draw(st.sampled_from([f.name for f in dataclasses.fields(cls)]))
    value = data.draw(_ANY_VALUE)
    try:
        option = cls(**{field: value})
    except (TypeError, ValueError) as error:
        assert field in str(error), (cls.__name__, field, value, error)
        return
    stored = getattr(option, field)
    assert _sane(stored), (cls.__name__, field, value, stored)
    assert cls(**{field: value}) == option  # the same twice
    repr(option)


@pytest.mark.parametrize("cls, field, value", [
    (CloudOption, "normal_radius", 0.0),
    (CloudOption, "normal_radius", -1.0),
    (CloudOption, "camera_location", (0.0, float("nan"), 1.0)),
    (CloudOption, "target_viewpoint", (float("inf"), 0.0, 1.0)),
    (SpectralRegistrationOption, "peak_width", float("inf")),
    (SpectralRegistrationOption, "egi_binned", "False"),
    (SpectralRegistrationOption, "bandwidth", 16.0),
    (SpectralRegistrationOption, "lambda_t", True),
    (SpectralRegistrationOption, "egi_smoothing", (0.3, float("nan"))),
    (SpectralRegistrationOption, "max_grid_memory", float("nan")),
    (GlobalSearchOption, "climbs", 64),
    (RefinementOption, "distance", float("nan")),
    (SpectralConvergenceCriteria, "max_iteration", 0),
])
def test_issue_options_are_refused_by_name(cls, field, value):
    """The options the issue found accepted and silently wrong."""
    with pytest.raises((TypeError, ValueError), match=field):
        cls(**{field: value})


# ---------------------------------------------------------------------------- clouds


@st.composite
def clouds(draw, normals=True):
    """Small clouds (N, 3) or (N, 6): random boxes, planes, lines, single points, at
    offsets up to 1e5 m, sometimes with a NaN or infinite entry."""
    n = draw(st.integers(1, 80))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    shape = draw(st.sampled_from(["box", "plane", "line", "point", "thin"]))
    size = draw(st.sampled_from([0.05, 0.2, 0.5]))
    points = rng.uniform(-size / 2, size / 2, (n, 3))
    if shape == "plane":
        points[:, 2] = 0.0
    elif shape == "line":
        points[:, 1:] = 0.0
    elif shape == "point":
        points[:] = points[0]
    elif shape == "thin":
        points[:, 2] *= 1e-4
    points += draw(st.sampled_from([0.0, 1.0, -1e3, 1e5]))
    array = points
    if normals:
        array = np.hstack([points, rng.normal(size=(n, 3))])
    if draw(st.booleans()) and draw(st.booleans()):
        array[draw(st.integers(0, n - 1)), draw(st.integers(0, array.shape[1] - 1))] = draw(
            st.sampled_from([np.nan, np.inf, -np.inf]))
    return array


def _register(source, target, call):
    if call == "global":
        return o3d_spectral.registration_spectral_global(
            source, target, VOXEL, SpectralRegistrationOption(bandwidth=4),
            search=GlobalSearchOption(hypotheses=4, climbs=2, hypothesis_iterations=3))
    return o3d_spectral.registration_spectral(source, target, VOXEL)


def _check_contract(source_array, target_array, call):
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(source_array[:, :3]))
    if source_array.shape[1] == 6:
        source.normals = o3d.utility.Vector3dVector(source_array[:, 3:])
    kept = source_array.copy(), target_array.copy()
    outcomes = []
    for _ in range(2):
        try:
            outcomes.append(_register(source, target_array, call).transformation)
        except (ValueError, TypeError) as error:
            assert "source" in str(error) or "target" in str(error), error
            outcomes.append(str(error))
    event("refused" if isinstance(outcomes[0], str) else "registered")  # both are drawn
    np.testing.assert_array_equal(np.asarray(source.points), kept[0][:, :3])
    np.testing.assert_array_equal(target_array, kept[1])
    if isinstance(outcomes[0], str):
        assert outcomes[0] == outcomes[1]
    else:
        assert_rigid(outcomes[0])
        np.testing.assert_array_equal(outcomes[0], outcomes[1])


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(source=clouds(), shift=st.tuples(*[st.floats(-0.05, 0.05)] * 3),
       call=st.sampled_from(["local", "global"]))
def test_any_cloud_with_normals_registers_or_is_refused_by_name(source, shift, call):
    target = source.copy()
    target[:, :3] += shift
    _check_contract(source, target, call)


@pytest.mark.slow
@settings(max_examples=25, deadline=None)
@example(source=np.c_[np.random.default_rng(0).uniform(-0.1, 0.1, (60, 2)), np.zeros(60)],
         call="local")
@given(source=clouds(normals=False), call=st.sampled_from(["local", "global"]))
def test_any_cloud_without_normals_registers_or_is_refused_by_name(source, call):
    _check_contract(source, source + [0.01, 0.0, 0.0], call)


def test_tensor_and_legacy_inputs_are_not_modified():
    cloud = o3d.geometry.PointCloud(sample_model("mustard_bottle", 2000).points)  # no normals
    tensor = o3d.t.geometry.PointCloud.from_legacy(cloud)
    before = np.asarray(cloud.points).copy(), tensor.point.positions.numpy().copy()
    o3d_spectral.registration_spectral(cloud, tensor, VOXEL)
    np.testing.assert_array_equal(np.asarray(cloud.points), before[0])
    np.testing.assert_array_equal(tensor.point.positions.numpy(), before[1])
    assert not cloud.has_normals() and "normals" not in tensor.point


# ------------------------------------------------ defects whose fix is in the core modules


def _model(n=3000, normals=True):
    cloud = sample_model("mustard_bottle", n)
    return (np.hstack([np.asarray(cloud.points), np.asarray(cloud.normals)]) if normals
            else np.asarray(cloud.points).copy())


@pytest.mark.slow
def test_threads_give_bit_identical_results_to_serial_calls():
    source = _model(2000, normals=False)
    rng = np.random.default_rng(3)
    jobs = []
    for _ in range(4):  # same-sized clouds: one FFT shape, one shared plan
        T = np.eye(4)
        T[:3, 3] = rng.uniform(-0.02, 0.02, 3)
        jobs.append((source, source @ T[:3, :3].T + T[:3, 3]))

    def run(job):
        return o3d_spectral.registration_spectral(job[0], job[1], VOXEL,
                                                  refinement=None).transformation

    serial = [run(job) for job in jobs]
    for _ in range(2):
        with ThreadPoolExecutor(len(jobs)) as pool:
            threaded = list(pool.map(run, jobs))
        for a, b in zip(serial, threaded, strict=True):
            np.testing.assert_array_equal(a, b)


def test_plane_through_the_origin_without_normals():
    g = np.linspace(-0.1, 0.1, 30)
    plane = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    result = o3d_spectral.registration_spectral(plane, plane + [0.01, 0.0, 0.0], VOXEL)
    assert_rigid(result.transformation)


def test_georeferenced_cloud_without_normals():
    points = _model(normals=False) + [500_000.0, 4_000_000.0, 100.0]
    result = o3d_spectral.registration_spectral(points, points + [0.01, 0, 0], VOXEL)
    moved = points @ result.transformation[:3, :3].T + result.transformation[:3, 3]
    assert np.abs(moved - (points + [0.01, 0, 0])).max() < 1e-3


def test_large_absolute_coordinates_give_the_same_pose_as_near_the_origin():
    points = _model(normals=False)
    shift = np.array([0.01, -0.005, 0.0])
    near = o3d_spectral.registration_spectral(points, points + shift, VOXEL).transformation
    offset = np.array([1e5, -1e5, 1e5])
    far = o3d_spectral.registration_spectral(points + offset, points + offset + shift,
                                             VOXEL).transformation
    np.testing.assert_allclose(far[:3, :3], near[:3, :3], atol=1e-6)
    # the same motion of the points (t_far = t_near + offset - R offset, where a 1e-6
    # difference in R is 0.1 m at 1e5 m: compare the moved points instead)
    moved_far = (points + offset) @ far[:3, :3].T + far[:3, 3] - offset
    moved_near = points @ near[:3, :3].T + near[:3, 3]
    np.testing.assert_allclose(moved_far, moved_near, atol=1e-5)


def test_open3d_criteria_are_refused_by_name():
    points = _model()
    with pytest.raises(TypeError, match="criteria"):
        o3d_spectral.registration_spectral(
            points, points, VOXEL,
            criteria=o3d.pipelines.registration.ICPConvergenceCriteria())


@pytest.mark.parametrize("distance", [-1.0, 0.0, float("nan"), float("inf")])
def test_bad_max_correspondence_distance_is_refused_by_name(distance):
    points = _model()
    with pytest.raises((TypeError, ValueError), match="max_correspondence_distance"):
        o3d_spectral.registration_spectral(points, points, VOXEL,
                                           max_correspondence_distance=distance)


def test_global_search_grid_stays_within_max_grid_memory():
    points = _model()
    option = SpectralRegistrationOption(max_grid_memory=2**20)  # voxel grids fit in 1 MiB
    o3d_spectral.registration_spectral(points, points, VOXEL, option=option)
    with pytest.raises(ValueError, match="max_grid_memory"):  # 64^3 complex: 4 MiB
        o3d_spectral.registration_spectral_global(points, points, VOXEL, option)


# ------------------------------------------------ voxel_size and init of any Python type


_ANY_OBJECT = st.one_of(
    _ANY_VALUE, st.decimals(allow_nan=True), st.fractions(), st.complex_numbers(),
    st.floats(min_value=0.0, max_value=1e-9), st.just(1e-300), st.just(10**400),
    st.sampled_from([np.float32(0.02), np.float16(0.02), np.int8(1)]), st.just(np.bool_(True)),
    st.builds(np.array, st.lists(st.floats(), max_size=3)),
)


@st.composite
def _inits(draw):
    """4x4 things of every type near a pose, and things that are not 4x4 at all."""
    from scipy.spatial.transform import Rotation

    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(draw(st.tuples(*[st.floats(-0.2, 0.2)] * 3))).as_matrix()
    pose[:3, 3] = draw(st.tuples(*[st.floats(-0.02, 0.02)] * 3))
    noise = draw(st.sampled_from([0.0, 1e-7, 1e-5, 1e-3, 0.1]))
    noisy = pose + noise * np.random.default_rng(draw(st.integers(0, 99))).normal(size=(4, 4))
    noisy[3] = pose[3]
    return draw(st.one_of(
        st.just(pose), st.just(noisy), st.just(np.round(pose, draw(st.integers(3, 8)))),
        st.just(pose.tolist()), st.just(pose.astype(np.float32)), st.just(pose.astype(complex)),
        st.just(pose.astype(bool)), st.just(pose[:3]), st.just(np.diag([1.0, 1.0, -1.0, 1.0])),
        st.just(o3d.core.Tensor(pose)), st.just(Rotation.from_matrix(pose[:3, :3])),
        st.just([[str(x) for x in row] for row in pose]), st.just("eye"),
        st.just([[fractions.Fraction(x) for x in row] for row in pose]),
        _ANY_OBJECT,
    ))


_SMALL = None


def _small_pair():
    global _SMALL
    if _SMALL is None:
        _SMALL = _model(1500)
    return _SMALL


def _registers_or_names(name, **arguments):
    """The local call either returns a finite rigid pose or raises TypeError / ValueError
    naming ``name``; never a warning, never another error."""
    source = _small_pair()
    target = source + [0.005, 0.0, 0.0, 0.0, 0.0, 0.0]
    kept = source.copy()
    arguments = {"voxel_size": VOXEL, "init": np.eye(4)} | arguments
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's ComplexWarning, a DeprecationWarning...
        try:
            result = o3d_spectral.registration_spectral(
                source, target, arguments["voxel_size"], arguments["init"],
                criteria=SpectralConvergenceCriteria(max_iteration=3), refinement=None)
        except (TypeError, ValueError) as error:
            assert name in str(error), error
            assert "\x1b" not in str(error)  # no terminal colour codes from Open3D
            event(type(error).__name__)
            return None
    np.testing.assert_array_equal(source, kept)
    assert_rigid(result.transformation)
    event("registered")
    return result


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@example(voxel_size="0.02")
@example(voxel_size=None)
@example(voxel_size=[0.02])
@example(voxel_size=0.02 + 0j)
@example(voxel_size=decimal.Decimal("0.02"))
@example(voxel_size=fractions.Fraction(1, 50))
@example(voxel_size=1e-12)
@example(voxel_size=1e-300)
@example(voxel_size=True)
@given(voxel_size=_ANY_OBJECT)
def test_voxel_size_of_any_type_registers_or_is_refused_by_name(voxel_size):
    result = _registers_or_names("voxel_size", voxel_size=voxel_size)
    if result is not None:  # only real numbers (not bools) are taken
        assert isinstance(voxel_size, numbers.Real) and not isinstance(voxel_size, bool | np.bool_)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(init=_inits())
def test_init_of_any_type_registers_or_is_refused_by_name(init):
    _registers_or_names("init", init=init)


@pytest.mark.parametrize("shift", [1e300, 1e30, 1e6])
def test_an_init_beyond_any_grid_is_refused_by_name(shift):
    """A translation no voxel grid over both clouds could span (an overflow, once)."""
    source = _small_pair()
    init = np.eye(4)
    init[1, 3] = -shift
    with pytest.raises(ValueError, match=r"^init places the source so far from the target"):
        o3d_spectral.registration_spectral(source, source, VOXEL, init)


@pytest.mark.parametrize("option, name", [
    (dict(peak_width=1e300), "peak_width"), (dict(peak_width=2**62), "peak_width"),
    (dict(egi_voxel_size=1e-300), "egi_voxel_size"),
    (dict(egi_voxel_size=1e300), "egi_voxel_size")])
def test_an_option_finite_but_beyond_any_grid_is_refused_by_name(option, name):
    source = _small_pair()
    with pytest.raises(ValueError, match=rf"^{name}="):
        o3d_spectral.registration_spectral(
            source, source, VOXEL, np.eye(4), option=SpectralRegistrationOption(**option))


def test_counts_beyond_what_exists_are_what_exists():
    """More hypotheses than the SO(3) grid has peaks, a polish cell finer than floats
    resolve: the call runs, with every peak, with every point."""
    source = _small_pair()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = o3d_spectral.registration_spectral_global(
            source, source, VOXEL, search=GlobalSearchOption(hypotheses=2**62),
            refinement=RefinementOption(cell=1e-300))
    assert_rigid(result.transformation)


def test_near_rigid_init_is_made_rigid_and_far_from_rigid_refused():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    for _ in range(50):  # a pose written with 5 decimals is used, exactly rigid
        pose = np.eye(4)
        pose[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        M = check_transformation(np.round(pose, 5))
        assert_rigid(M)
        np.testing.assert_allclose(M, pose, atol=1e-5)
    sheared = np.eye(4)
    sheared[0, 1] = 1e-3
    with pytest.raises(ValueError, match=r"init .*rigid.*tolerance"):
        check_transformation(sheared)
    with pytest.raises(TypeError, match="init"):
        check_transformation("eye")
    with pytest.raises(TypeError, match="init"):
        check_transformation(Rotation.identity())
    np.testing.assert_array_equal(check_transformation(o3d.core.Tensor(np.eye(4))), np.eye(4))


@pytest.mark.parametrize("kind", [complex, bool])
def test_complex_and_bool_points_are_refused_by_name(kind):
    points = _model(500, normals=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(TypeError, match=f"source.*{kind.__name__}"):
            o3d_spectral.registration_spectral(points.astype(kind), points, VOXEL)


# ------------------------------------------------ distance from the origin, large inputs


@pytest.mark.slow
@pytest.mark.parametrize("distance", [50.0, 80.0])
def test_pose_does_not_depend_on_the_distance_from_the_origin(distance):
    """A model into a partial view of it, moved whole: the same pose (and the polish kept)
    at 0 m and 10-100 m, where the ICP's linearisation about the origin used to throw
    the source off the surface."""
    from scipy.spatial.transform import Rotation

    model = _model(6000)
    view = sample_model("mustard_bottle", 6000, seed=1)
    points, normals = np.asarray(view.points), np.asarray(view.normals)
    keep = points[:, 0] > np.percentile(points[:, 0], 30)  # a part of it
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_euler("xyz", [40, -30, 70], degrees=True).as_matrix()
    motion[:3, 3] = [0.03, -0.02, 0.05]
    target = np.hstack([points[keep] @ motion[:3, :3].T + motion[:3, 3],
                        normals[keep] @ motion[:3, :3].T])
    offset = np.array([0.6, -0.48, 0.64]) * distance
    shift = np.eye(4)
    shift[:3, 3] = offset
    near = o3d_spectral.registration_spectral_global(model, target, 0.008)
    far = o3d_spectral.registration_spectral_global(
        model + np.r_[offset, 0, 0, 0], target + np.r_[offset, 0, 0, 0], 0.008)
    back = np.linalg.inv(shift) @ far.transformation @ shift
    moved = [model[:, :3] @ T[:3, :3].T + T[:3, 3] for T in (near.transformation, back)]
    assert np.max(np.linalg.norm(moved[0] - moved[1], axis=1)) < 1e-6
    assert far.fitness == pytest.approx(near.fitness, abs=1e-9)


@pytest.mark.slow
def test_polish_and_score_cost_the_cells_not_the_raw_points(monkeypatch):
    """A dense source (200k points, about 300 per 2 cm voxel) is polished and scored one
    point per quarter-voxel cell; the correspondence indices still point into the
    caller's clouds."""
    from o3d_spectral import run

    dense = sample_model("mustard_bottle", 200_000)
    points = np.asarray(dense.points)
    target = points + [0.004, 0.0, 0.0]
    seen = []
    refine = run.refine

    def spy(source, *args):
        seen.append(len(source.points))
        return refine(source, *args)

    monkeypatch.setattr(run, "refine", spy)
    result = o3d_spectral.registration_spectral(points, target, VOXEL)
    cells = len(np.unique(np.floor((points - points.min(axis=0)) / (0.25 * VOXEL)), axis=0))
    assert seen == [cells] and cells < len(points) / 10
    pairs = np.asarray(result.correspondence_set)
    assert len(pairs) <= cells and result.fitness > 0.9
    moved = points[pairs[:, 0]] @ result.transformation[:3, :3].T + result.transformation[:3, 3]
    assert np.max(np.linalg.norm(moved - target[pairs[:, 1]], axis=1)) <= VOXEL
