"""The search on a device: names read as Open3D writes them, CUDA refused clearly when it
cannot be used, and the CUDA path's code run here on NumPy behind CuPy's interface."""

from __future__ import annotations

import contextlib
import sys
import types

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.common.extras import MissingExtraError
from o3d_spectral.correlation import (
    ArrayBackend,
    BatchedCorrelation,
    CompiledBackend,
    Device,
    TurnedCloud,
    device_backend,
    parse_device,
)
from o3d_spectral.harness.errors import rotation_error
from o3d_spectral.search.dense import dense_candidates
from o3d_spectral.spectra import so3


class FakeOutOfMemory(Exception):
    """CuPy's allocator's error, which is not a MemoryError of Python's."""


def fake_cupy(devices: int = 1, free: int = 64 * 2**20, fail_above: int | None = None):
    """A module with CuPy's interface over NumPy: ``cuda.Device`` (a context with
    ``mem_info``), ``cuda.runtime.getDeviceCount``, ``cuda.memory.OutOfMemoryError``,
    ``asnumpy``, and ``fft`` whose forward transform runs out of memory past
    ``fail_above`` grids; and its ``cupyx`` (``scatter_add``)."""
    cupy = types.ModuleType("cupy")
    for name in ("asarray", "einsum", "ones", "zeros", "floor", "arange", "all", "add",
                 "sum", "abs", "conj", "maximum", "argmax", "int64",
                 "float32", "float64", "complex64", "empty", "stack", "unravel_index",
                 "sqrt", "where"):
        setattr(cupy, name, getattr(np, name))
    cupy.asnumpy = np.asarray
    entered = []

    class Device:
        def __init__(self, index=0):
            self.index, self.mem_info = index, (free, 2 * free)

        def __enter__(self):
            entered.append(self.index)

        def __exit__(self, *exc):
            return False

    def rfftn(grids, s, axes):
        if fail_above is not None and len(grids) > fail_above:
            raise FakeOutOfMemory("out of memory allocating 1 GiB")
        return np.fft.rfftn(grids, s=s, axes=axes)

    cupy.fft = types.SimpleNamespace(rfftn=rfftn, irfftn=np.fft.irfftn)
    cupy.cuda = types.SimpleNamespace(
        Device=Device, runtime=types.SimpleNamespace(getDeviceCount=lambda: devices),
        memory=types.SimpleNamespace(OutOfMemoryError=FakeOutOfMemory))
    cupy.entered = entered
    cupyx = types.ModuleType("cupyx")
    cupyx.scatter_add = np.add.at
    return cupy, cupyx


@contextlib.contextmanager
def installed(cupy, cupyx):
    saved = {name: sys.modules.get(name) for name in ("cupy", "cupyx")}
    sys.modules["cupy"], sys.modules["cupyx"] = cupy, cupyx
    try:
        yield
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module


# ------------------------------------------------------------------------------- names


@pytest.mark.parametrize("given, read", [
    (None, "CPU:0"), ("CPU:0", "CPU:0"), ("cpu", "CPU:0"), ("cuda", "CUDA:0"),
    (" CUDA:2 ", "CUDA:2"), (o3d.core.Device("CPU:0"), "CPU:0"),
    (o3d.core.Device("CUDA:1"), "CUDA:1"), (Device("CUDA", 3), "CUDA:3"),
])
def test_devices_are_read_as_open3d_names_them(given, read):
    assert str(parse_device(given)) == read


@pytest.mark.parametrize("given, error", [
    ("GPU", ValueError), ("CPU:1", ValueError), ("cuda:-1", ValueError), ("", ValueError),
    (0, TypeError), (["CUDA:0"], TypeError), (b"CUDA:0", TypeError),
])
def test_other_devices_are_refused_by_name(given, error):
    with pytest.raises(error, match="^device"):
        parse_device(given)


def test_the_cpu_runs_the_compiled_backend():
    assert isinstance(device_backend(Device()), CompiledBackend)


def test_cuda_without_cupy_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "cupy", None)  # import cupy fails
    with pytest.raises(MissingExtraError, match=r"device='CUDA:0' needs the 'gpu' extra"):
        device_backend(parse_device("CUDA:0"))


def test_cuda_that_cannot_be_used_says_why():
    cupy, cupyx = fake_cupy(devices=1)
    with installed(cupy, cupyx):
        assert isinstance(device_backend(Device("CUDA", 0)), ArrayBackend)
        with pytest.raises(ValueError, match=r"device='CUDA:1' does not exist: 1 CUDA device "
                                             "found"):
            device_backend(parse_device("CUDA:1"))
        cupy.cuda.runtime.getDeviceCount = lambda: (_ for _ in ()).throw(
            RuntimeError("cudaErrorNoDevice: no CUDA-capable\n device is detected"))
        with pytest.raises(ValueError, match="device='CUDA:0' is not usable: cudaErrorNoDevice: "
                                             "no CUDA-capable device is detected$"):
            device_backend(parse_device("CUDA:0"))


# ------------------------------------------------------------- the CUDA path on NumPy


@pytest.fixture
def lumpy(rng):
    points = rng.normal(size=(400, 3)) * [3.0, 2.0, 1.5]
    fixed = BatchedCorrelation.grid_of(TurnedCloud(points, [10.0, 9.0, 11.0]), (20, 18, 22),
                                       so3.exp([0.3, -0.5, 0.2]))
    return points, fixed


def test_the_gpu_path_gives_the_cpu_peaks_and_splits_what_does_not_fit(lumpy):
    """Batches sized from the device's free memory, run inside its context; out of
    memory past 5 grids: split into smaller batches, the same peaks."""
    points, fixed = lumpy
    moving = TurnedCloud(points, [8.0, 8.0, 8.0])
    rotations = np.stack([so3.exp([0.3, -0.5, 0.2]), *so3.uniform_rotations(23)])
    cpu = BatchedCorrelation(fixed, (16, 16, 16)).peaks(moving, rotations)
    cupy, cupyx = fake_cupy(fail_above=5)
    with installed(cupy, cupyx):
        backend = device_backend(parse_device("CUDA:0"))
        assert backend.batch_size((32, 32, 32)) == int(0.25 * 64 * 2**20) // (32 * 32**3)
        gpu = BatchedCorrelation(fixed, (16, 16, 16), backend=backend).peaks(moving, rotations)
    assert cupy.entered and set(cupy.entered) == {0}
    np.testing.assert_allclose(gpu.heights, cpu.heights, rtol=1e-4)
    np.testing.assert_array_equal(gpu.shifts, cpu.shifts)
    assert np.argmax(gpu.heights) == np.argmax(cpu.heights) == 0


@pytest.fixture(scope="module")
def pair():
    from tests.conftest import sample_model

    source = sample_model("mustard_bottle", 4000, seed=1)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = so3.exp([0.4, 1.1, -0.6]), [0.05, -0.02, 0.01]
    return source, o3d.geometry.PointCloud(source).transform(T), T


def test_the_dense_search_ranks_alike_on_cuda(pair):
    """The dense search's candidates on ``"CUDA:0"`` (CuPy's interface, NumPy behind it):
    the CPU's, the truth first."""
    source, target, truth = pair
    cupy, cupyx = fake_cupy(free=256 * 2**20)
    found = {}
    for device in ("CPU:0", "CUDA:0"):
        with installed(cupy, cupyx):
            stepper = o3d_spectral.SpectralStepper(target, 0.008, device=device)
            found[device] = dense_candidates(stepper, stepper.moving(source), 300,
                                             two_scans=False)
    assert cupy.entered  # the correlations ran inside the device's context
    assert [c.key for c in found["CUDA:0"]] == [c.key for c in found["CPU:0"]]
    np.testing.assert_allclose([c.value for c in found["CUDA:0"]],
                               [c.value for c in found["CPU:0"]], rtol=1e-4)
    best = np.eye(4)
    best[:3, :3] = found["CUDA:0"][0].rotation
    assert rotation_error(best, truth) < 10.0


def test_a_global_call_on_cuda_registers(pair):
    """(A model onto its moved copy is confirmed before any batched correlation: the
    dense search's own run on the device is the test above.)"""
    source, target, truth = pair
    cupy, cupyx = fake_cupy(free=256 * 2**20)
    with installed(cupy, cupyx):
        result = o3d_spectral.registration_spectral_global(source, target, 0.008,
                                                           device="CUDA:0")
    assert rotation_error(result.transformation, truth) < 2.0


def test_auto_is_dense_on_a_gpu_and_escalating_on_the_cpu():
    auto = o3d_spectral.GlobalSearchOption()
    assert auto.rotations == "auto"
    assert (auto.sweep_on(True), auto.sweep_on(False)) == ("dense", "escalating")
    chosen = o3d_spectral.GlobalSearchOption(rotations="adaptive")
    assert chosen.sweep_on(True) == "adaptive"


# --------------------------------------------------------------- calls and the CLI


def test_a_prepared_target_keeps_its_device(pair):
    source, target, _ = pair
    prepared = o3d_spectral.prepare_target(target, 0.008, device="CPU:0")
    assert str(prepared.device) == "CPU:0"
    with pytest.raises(ValueError, match=r"target was prepared with device='CPU:0'.*'CUDA:0'"):
        o3d_spectral.registration_spectral_global(source, prepared, 0.008, device="CUDA:0")


def test_cuda_without_cupy_is_one_line_from_the_call_and_the_command(pair, monkeypatch,
                                                                    tmp_path, capsys):
    from o3d_spectral.cli import main

    source, target, _ = pair
    monkeypatch.setitem(sys.modules, "cupy", None)
    with pytest.raises(MissingExtraError, match="pip install 'o3d-spectral\\[gpu\\]'"):
        o3d_spectral.registration_spectral_global(source, target, 0.008, device="CUDA:0")
    for name, cloud in (("s.ply", source), ("t.ply", target)):
        o3d.io.write_point_cloud(str(tmp_path / name), cloud)
    assert main(["register", str(tmp_path / "s.ply"), str(tmp_path / "t.ply"),
                 "--voxel-size", "0.008", "--device", "CUDA:0"]) == 1
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "o3d-spectral register: error: device='CUDA:0' needs the 'gpu' extra (cupy is "
        "missing): pip install 'o3d-spectral[gpu]'")
    assert main(["register", "s.ply", "t.ply", "--voxel-size", "0.008", "--device",
                 "GPU:0"]) == 2
