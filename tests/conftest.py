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


def thin_walled_cup(
    n: int = 3000, *, wall: float = 0.002, radius: float = 0.04, height: float = 0.06,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Points (metres) and outward unit normals, shape (n, 3) each, sampled uniformly on
    a cup of ``wall`` metres thick: an open cylinder (axis z, from z = 0) and its
    bottom, each as two faces ``wall`` apart whose normals point away from each other
    (out of the ceramic: the outer faces outward, the inner ones into the cup)."""
    rng = np.random.default_rng(seed)
    side, base = 2 * np.pi * radius * height, np.pi * radius**2
    face = rng.choice(4, size=n, p=np.array([side, side, base, base]) / (2 * (side + base)))
    angle, z = rng.uniform(0.0, 2 * np.pi, n), rng.uniform(0.0, height, n)
    ring = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    r = np.select([face == 0, face == 1], [radius, radius - wall],
                  (radius - wall) * np.sqrt(rng.uniform(0.0, 1.0, n)))
    z = np.select([face <= 1, face == 2], [z, 0.0], wall)
    points = ring * r[:, None] + np.outer(z, [0.0, 0.0, 1.0])
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    normals = np.select([face[:, None] == 0, face[:, None] == 1, face[:, None] == 2],
                        [ring, -ring, -up], up)
    return points, normals
