"""The servoing loop (paper, Algorithm 1) at a fixed control period.

Capture the reference cloud at the desired pose and compute its spectra once; then each
cycle: capture the whole scene, compute the control law's increments
(:meth:`o3d_spectral.servo.ServoLaw.step`), turn them into a camera twist, map it to
joint velocities with the damped pseudo-inverse of the camera-frame Jacobian, limit them,
integrate for one period. Stop when both of the law's full corrections, at the finest EGI
smoothing level, are below their tolerances (the paper's gradient test, with one
tolerance per unit as in :class:`o3d_spectral.SpectralConvergenceCriteria`) or at the
time limit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..options import CloudOption, SpectralRegistrationOption
from ..search.options import GlobalSearchOption
from ..spectra import so3
from .constants import DESIRED_POSE_ATTEMPTS
from .control import camera_twist, joint_velocities, limit_velocities
from .law import ServoLaw
from .robot import Arm
from .scene import Sensor, Start, Tabletop, desired_pose, make_tabletop, sample_start

__all__ = ["ServoOptions", "Cycle", "ServoRun", "Trial", "pose_errors", "servo", "random_trial",
           "draw_trial"]


@dataclass(frozen=True)
class ServoOptions:
    """Settings of a servoing run (metres, radians, seconds).

    Attributes
    ----------
    period : float
        Control period: simulated time between two captures.
    max_time : float
        Simulated time limit.
    voxel_size : float
        Voxel edge of the law's grids. The paper uses 0.008; whole-scene grids are large
        (FFTs of about 160^3 at 0.01 m, 210^3 at 0.008 m), so 0.01 halves the time per cycle.
    translation_tolerance : float
        Stop when the full translation correction is below this (metres) ...
    rotation_tolerance : float
        ... and the full rotation step below this (radians).
    damping : float
        Damping of the pseudo-inverse (:func:`~o3d_spectral.servo.control.damped_pseudo_inverse`).
    limit_margin : float
        Joints are stopped this far inside their URDF limits.
    registration : SpectralRegistrationOption
        The control law's settings (gains ``lambda_t``, ``lambda_r``, ...). Default: the
        library's with half its translation gain (``lambda_t=0.25``): from 30-40 degrees
        the camera then translates less before the rotation has settled; and with normals
        averaged in 5 mm cells for the EGI (``egi_voxel_size``; the library's default is
        a quarter voxel, 2.5 mm here), coarser than this 320 x 240 sensor's spacing of
        about 2 mm at 0.6 m, so that oblique surfaces are not under-counted
        (docs/servo.md).
    cloud : CloudOption
        Default: no back-face culling (``target_viewpoint=None``): both clouds are single
        views in their own sensor frames, so the culling's incidence weighting would
        weigh the current cloud's EGI and not the reference's.
    search : GlobalSearchOption or None
        The global search first (:class:`~o3d_spectral.servo.ServoLaw`), on a 128^3
        Euler grid: from 30-40 degrees the law alone may climb a wrong peak of the
        whole-scene correlation. None: the paper's law alone.
    handover_angle : float
        The law takes over once the best hypothesis' rotation is this close to the
        identity, radians: well inside the law's basin (alone it succeeds from 30-40
        degrees on 25 of the 30 seeded scenes), so that the global search, whose cycles
        cost seconds, stops as soon as the law can finish (30 of 30 at 3 or 6 degrees;
        at 6, 252 search cycles of 981 instead of 282 of 878, and 15% less controller
        time in all).
    law_reach : float
        When the law's increments since the handover add up to a turn larger than this
        (radians), the global search starts again.
    """

    period: float = 0.1
    max_time: float = 20.0
    voxel_size: float = 0.01
    translation_tolerance: float = 5e-4
    rotation_tolerance: float = np.deg2rad(0.05)
    damping: float = 0.01
    limit_margin: float = np.deg2rad(1.0)
    registration: SpectralRegistrationOption = field(
        default_factory=lambda: SpectralRegistrationOption(lambda_t=0.25, egi_voxel_size=0.005)
    )
    cloud: CloudOption = field(default_factory=lambda: CloudOption(target_viewpoint=None))
    search: GlobalSearchOption | None = field(
        default_factory=lambda: GlobalSearchOption(search_samples=128)
    )
    handover_angle: float = np.deg2rad(6.0)
    law_reach: float = np.deg2rad(15.0)

    def __post_init__(self) -> None:
        for name in ("period", "max_time", "voxel_size", "translation_tolerance",
                     "rotation_tolerance", "handover_angle", "law_reach"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("damping", "limit_margin"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class Cycle:
    """What happened in one control cycle.

    Attributes
    ----------
    time : float
        Simulated time of the capture, seconds from the start.
    q : ndarray, shape (7,)
        Joint positions at the capture, radians.
    world_from_camera : ndarray, shape (4, 4)
        Camera pose at the capture.
    translation_error, rotation_error : float
        Distance (metres) and angle (radians) to the desired camera pose.
    translation_correction, rotation_correction : float
        Norms of the law's full corrections (metres, radians): the stop test's terms.
    controller_time : float
        Wall-clock seconds of the controller (law, twist, Jacobian, limits; capture
        excluded).
    points : int
        Points in the captured cloud.
    qdot : ndarray, shape (7,)
        Joint velocities commanded for the next period, rad/s (zero on the last cycle).
    searched : bool
        Whether the cycle ran the global search (:attr:`ServoLaw.searching` at its start).
    """

    time: float
    q: NDArray[np.float64]
    world_from_camera: NDArray[np.float64]
    translation_error: float
    rotation_error: float
    translation_correction: float
    rotation_correction: float
    controller_time: float
    points: int
    qdot: NDArray[np.float64]
    searched: bool = False


@dataclass
class ServoRun:
    """A servoing run.

    Attributes
    ----------
    desired_q : ndarray, shape (7,)
    desired_pose : ndarray, shape (4, 4)
        ``world_from_camera`` where the reference was captured.
    cycles : list of Cycle
    converged : bool
        Whether the gradient test stopped the run (False: the time limit did).
    limit_violations : int
        Cycles at which some joint lay outside its URDF range.
    """

    desired_q: NDArray[np.float64]
    desired_pose: NDArray[np.float64]
    cycles: list[Cycle]
    converged: bool
    limit_violations: int

    @property
    def final(self) -> Cycle:
        """The last cycle."""
        return self.cycles[-1]

    def median_controller_time(self) -> float:
        """Median controller time per cycle, seconds."""
        return float(np.median([c.controller_time for c in self.cycles]))


def pose_errors(pose: NDArray, desired: NDArray) -> tuple[float, float]:
    """Distance (metres) and angle (radians) between two camera poses (4, 4)."""
    return (
        float(np.linalg.norm(pose[:3, 3] - desired[:3, 3])),
        so3.rotation_angle(desired[:3, :3].T @ pose[:3, :3]),
    )


def servo(
    arm: Arm,
    sensor: Sensor,
    scene: Tabletop,
    *,
    desired_q: NDArray,
    start_q: NDArray,
    rng: np.random.Generator,
    options: ServoOptions | None = None,
) -> ServoRun:
    """Drive the camera from ``start_q`` to where it sees what it saw at ``desired_q``.

    Parameters
    ----------
    arm : Arm
    sensor : Sensor
    scene : Tabletop
        The static scene, world frame.
    desired_q, start_q : ndarray, shape (7,)
        Joint positions (radians) of the reference capture and of the start.
    rng : numpy.random.Generator
        Sensor noise.
    options : ServoOptions, optional

    Returns
    -------
    ServoRun
    """
    options = options or ServoOptions()
    desired = arm.camera_pose(desired_q)
    reference = sensor.capture(scene, desired, rng=rng)
    law = ServoLaw(
        reference, options.voxel_size, option=options.registration, cloud=options.cloud,
        search=options.search, handover_angle=options.handover_angle,
        law_reach=options.law_reach,
    )
    tolerance = (options.translation_tolerance, options.rotation_tolerance)
    lower, upper = arm.lower + options.limit_margin, arm.upper - options.limit_margin
    q = np.asarray(start_q, dtype=np.float64).copy()
    cycles: list[Cycle] = []
    violations, converged = 0, False
    steps = int(round(options.max_time / options.period))
    for k in range(steps + 1):
        pose = arm.camera_pose(q)
        cloud = sensor.capture(scene, pose, rng=rng)
        tic = time.perf_counter()
        finest = law.finest  # the level this cycle's law uses
        searched = law.searching
        step = law.step(cloud)
        correction_t = float(np.linalg.norm(step.evaluation.translation))
        correction_r = float(np.linalg.norm(step.evaluation.rotation))
        converged = finest and step.evaluation.within(tolerance)
        qdot = np.zeros_like(q)
        if not converged and k < steps:
            twist = camera_twist(step.transformation, options.period)
            qdot = joint_velocities(arm.camera_jacobian(q), twist, damping=options.damping)
            qdot = limit_velocities(
                qdot, q, velocity_limit=arm.velocity_limit, lower=lower, upper=upper,
                period=options.period,
            )
        elapsed = time.perf_counter() - tic
        violations += not arm.within_limits(q)
        cycles.append(
            Cycle(k * options.period, q.copy(), pose, *pose_errors(pose, desired),
                  correction_t, correction_r, elapsed, len(cloud), qdot, searched)
        )
        if converged:
            break
        q = q + options.period * qdot
    return ServoRun(np.asarray(desired_q, float), desired, cycles, converged, violations)


@dataclass(frozen=True)
class Trial:
    """A seeded servoing experiment: the scene, the start and the run."""

    seed: int
    scene: Tabletop
    start: Start
    run: ServoRun


def draw_trial(
    seed: int, arm: Arm, sensor: Sensor
) -> tuple[Tabletop, NDArray[np.float64], Start, np.random.Generator]:
    """The tabletop, desired joint positions and start of trial ``seed``, and the
    generator (its state after the draws) that then drives the sensor noise.

    Every random choice comes from ``numpy.random.default_rng(seed)``. When no start meets
    :func:`~o3d_spectral.servo.scene.sample_start`'s constraints from the desired pose
    drawn, another desired pose is drawn (up to ``DESIRED_POSE_ATTEMPTS``).
    """
    rng = np.random.default_rng(seed)
    scene = make_tabletop(rng)
    attempts = DESIRED_POSE_ATTEMPTS
    while True:
        desired_q, desired = desired_pose(arm, scene, rng)
        try:
            return scene, desired_q, sample_start(arm, sensor, scene, desired, rng), rng
        except RuntimeError:  # no far, partly-out-of-view start from here: another pose
            attempts -= 1
            if attempts == 0:
                raise


def random_trial(
    seed: int, arm: Arm, sensor: Sensor, *, options: ServoOptions | None = None
) -> Trial:
    """Draw a tabletop, a desired pose and a far start from ``seed`` (:func:`draw_trial`),
    then servo; a seed reproduces a trial exactly."""
    scene, desired_q, start, rng = draw_trial(seed, arm, sensor)
    run = servo(arm, sensor, scene, desired_q=desired_q, start_q=start.q, rng=rng,
                options=options)
    return Trial(seed, scene, start, run)
