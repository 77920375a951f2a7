"""The depth sensor's model: pinhole intrinsics and axial noise with disparity quantisation.

Used by the virtual camera (:mod:`.camera`) to project and to turn exact depths into sensor
depths. Units: pixels and metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CameraIntrinsics", "DepthNoise"]

_EPS = 1e-12


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics (pixels).

    The defaults are a 640x480 sensor with a 60 degree horizontal field of view
    (``fx = fy = 320 / tan(30 deg)``) and the principal point at the image centre.
    Pixel ``(u, v)`` has its centre at column ``u``, row ``v``.
    """

    width: int = 640
    height: int = 480
    fx: float = 554.2562584220407
    fy: float = 554.2562584220407
    cx: float = 319.5
    cy: float = 239.5

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"width and height must be >= 1, got {self.width}x{self.height}")
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError(f"fx and fy must be > 0, got fx={self.fx}, fy={self.fy}")

    @classmethod
    def from_fov(cls, *, width: int = 640, height: int = 480, fov: float) -> CameraIntrinsics:
        """Square-pixel intrinsics from a horizontal field of view ``fov`` (radians)."""
        if not 0 < fov < np.pi:
            raise ValueError(f"fov must be in (0, pi) radians, got {fov}")
        f = 0.5 * width / np.tan(0.5 * fov)
        return cls(width=width, height=height, fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2)

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 calibration matrix ``K`` (float64)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(u, v)``, shape (N, 2), of camera-frame ``points`` (N, 3)."""
        z = np.maximum(points[:, 2], _EPS)
        return np.stack(
            [self.fx * points[:, 0] / z + self.cx, self.fy * points[:, 1] / z + self.cy], axis=1
        )


@dataclass(frozen=True)
class DepthNoise:
    """Depth-sensor model: axial Gaussian noise, disparity quantisation, range and dropout.

    Parameters
    ----------
    sigma_0, sigma_quadratic, sigma_offset : float
        Axial standard deviation ``sigma(z) = sigma_0 + sigma_quadratic * (z - sigma_offset)**2``
        in metres; the defaults are the structured-light (Kinect) fit of Nguyen et al.
        (2012): 1.2 mm at 0.4 m, 1.9 mm at 1 m, 5.8 mm at 2 m.
    baseline : float
        Projector-camera baseline (m) of the triangulation used for quantisation.
    disparity_step : float
        Disparity resolution (pixels). Depth is quantised as ``z = fx * baseline / d``
        with ``d`` rounded to this step, so the depth step grows as ``z**2``
        (about 3 mm at 1 m with the defaults). Zero disables quantisation.
    min_depth, max_depth : float
        Working range (m); pixels outside it are invalid (missing).
    max_incidence : float
        Surfaces seen at a larger angle (radians) between ray and normal return nothing,
        as on a real sensor at grazing incidence.

    References
    ----------
    C. V. Nguyen, S. Izadi, D. Lovell, "Modeling Kinect sensor noise for improved 3D
    reconstruction and tracking", 3DIMPVT 2012, doi:10.1109/3DIMPVT.2012.84.
    """

    sigma_0: float = 0.0012
    sigma_quadratic: float = 0.0019
    sigma_offset: float = 0.4
    baseline: float = 0.075
    disparity_step: float = 0.125
    min_depth: float = 0.2
    max_depth: float = 3.0
    max_incidence: float = np.deg2rad(80.0)

    def __post_init__(self) -> None:
        if self.sigma_0 < 0 or self.sigma_quadratic < 0:
            raise ValueError(
                f"sigma_0 and sigma_quadratic must be >= 0, got {self.sigma_0}, "
                f"{self.sigma_quadratic}"
            )
        if self.baseline <= 0 or self.disparity_step < 0:
            raise ValueError(
                f"baseline must be > 0 and disparity_step >= 0, got {self.baseline}, "
                f"{self.disparity_step}"
            )
        if not 0 <= self.min_depth < self.max_depth:
            raise ValueError(
                f"need 0 <= min_depth < max_depth, got {self.min_depth}, {self.max_depth}"
            )

    @classmethod
    def noiseless(cls) -> DepthNoise:
        """Exact depths: no noise, no quantisation, no grazing dropout (same range)."""
        return cls(sigma_0=0.0, sigma_quadratic=0.0, disparity_step=0.0, max_incidence=np.pi / 2)

    def sigma(self, depth: np.ndarray) -> np.ndarray:
        """Axial standard deviation (m) at ``depth`` (m), any shape."""
        return self.sigma_0 + self.sigma_quadratic * (depth - self.sigma_offset) ** 2

    def apply(self, depth: np.ndarray, *, fx: float, rng: np.random.Generator) -> np.ndarray:
        """Noisy, quantised copy of ``depth`` (m), shape (N,). Invalid results are NaN."""
        noisy = depth + rng.standard_normal(depth.shape) * self.sigma(depth)
        if self.disparity_step > 0:
            # Triangulation: depth comes from a disparity measured in steps of disparity_step.
            fb = fx * self.baseline
            disparity = np.round(fb / np.maximum(noisy, _EPS) / self.disparity_step)
            noisy = fb / np.maximum(disparity * self.disparity_step, _EPS)
        return np.where((noisy >= self.min_depth) & (noisy <= self.max_depth), noisy, np.nan)
