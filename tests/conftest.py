"""Shared fixtures: seeded random generators and small clouds from the bundled models."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.synthetic import models


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def full_suite(tmp_path_factory: pytest.TempPathFactory, n: int):
    """A seed-0 ``full`` suite of ``n`` instances in a fresh temporary folder."""
    from o3d_spectral.synthetic.suite import make_suite

    out = tmp_path_factory.mktemp("suites") / "full"
    make_suite("full", n, 0, out, progress=False)
    return out


def sample_model(name: str, n: int = 20000, seed: int = 0) -> o3d.geometry.PointCloud:
    """Points sampled uniformly on a bundled mesh, with outward triangle normals."""
    o3d.utility.random.seed(seed)
    return models.load_model(name).sample_points_uniformly(n, use_triangle_normal=True)


def band_limited(bandwidth: int, rng: np.random.Generator) -> np.ndarray:
    """Random coefficients (B, 2B - 1) with zeros where |m| > l."""
    F = rng.normal(size=(bandwidth, 2 * bandwidth - 1))
    m = np.arange(-(bandwidth - 1), bandwidth)
    return F * (np.abs(m)[None, :] <= np.arange(bandwidth)[:, None])
