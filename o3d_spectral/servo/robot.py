"""The arm: pybullet's bundled KUKA LBR iiwa URDF in DIRECT mode (no GUI, no dynamics).

pybullet supplies the kinematic model (``kuka_iiwa/model.urdf`` in ``pybullet_data``),
forward kinematics, the geometric Jacobian, the joint limits and inverse kinematics. The
simulation is kinematic: joint positions are set directly, as on an arm whose velocity
controller tracks the command within one control period.

Frames: ``world_from_base`` places the arm's base; the flange is the frame of
``lbr_iiwa_link_7``; the camera sits at :data:`HAND_EYE` (``flange_from_camera``), looking
along the tool axis, with the OpenCV convention of :mod:`o3d_spectral.synthetic.camera` (z forward,
x right, y down in the image).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..common import extras
from ..spectra import so3
from .constants import HAND_EYE

__all__ = ["HAND_EYE", "FLANGE_LINK", "Arm"]

#: Name of the flange link in the URDF.
FLANGE_LINK = "lbr_iiwa_link_7"


def load_pybullet():
    """pybullet and its data, or ``ImportError`` naming the ``servo`` extra."""
    what = "the servo simulation"
    return extras.require("pybullet", what), extras.require("pybullet_data", what)


def _pose(position: ArrayLike, quaternion: ArrayLike, pybullet) -> NDArray[np.float64]:
    """4x4 pose from a position and a pybullet ``(x, y, z, w)`` quaternion."""
    pose = np.eye(4)
    pose[:3, :3] = np.reshape(pybullet.getMatrixFromQuaternion(quaternion), (3, 3))
    pose[:3, 3] = position
    return pose


class Arm:
    """A 7-DOF iiwa with an eye-in-hand camera, simulated kinematically in pybullet.

    Parameters
    ----------
    world_from_base : array_like, shape (4, 4), optional
        Pose of the robot's base in the world (metres); identity when omitted.
    hand_eye : array_like, shape (4, 4), optional
        ``flange_from_camera``; :data:`HAND_EYE` when omitted.
    max_joint_velocity : float
        Cap (rad/s) on every joint's speed, on top of the URDF's ``velocity`` limit (10 rad/s
        in pybullet's iiwa file, several times what the real arm allows: its datasheets give
        75 to 180 deg/s per joint). 1 rad/s is below every joint's real limit.

    Attributes
    ----------
    lower, upper : ndarray, shape (7,)
        Joint position limits from the URDF, radians.
    velocity_limit : ndarray, shape (7,)
        ``min(URDF velocity, max_joint_velocity)``, rad/s.

    Notes
    -----
    Use as a context manager (or call :meth:`close`) to release the pybullet client.
    pybullet's link poses carry about 1e-7 m of rounding, far below what servoing resolves.
    """

    def __init__(
        self,
        *,
        world_from_base: ArrayLike | None = None,
        hand_eye: ArrayLike | None = None,
        max_joint_velocity: float = 1.0,
    ) -> None:
        if not max_joint_velocity > 0:
            raise ValueError(f"max_joint_velocity must be > 0 rad/s, got {max_joint_velocity}")
        base = np.eye(4) if world_from_base is None else np.asarray(world_from_base, float)
        self.hand_eye = HAND_EYE.copy() if hand_eye is None else np.asarray(hand_eye, float)
        for name, matrix in (("world_from_base", base), ("hand_eye", self.hand_eye)):
            if matrix.shape != (4, 4) or not so3.is_rotation(matrix[:3, :3]):
                raise ValueError(f"{name} must be a 4x4 rigid transform, got {matrix!r}")
        pybullet, data = load_pybullet()
        self._pb = pybullet
        self._client = pybullet.connect(pybullet.DIRECT)
        quaternion = _quaternion(base[:3, :3])
        self._robot = pybullet.loadURDF(
            str(Path(data.getDataPath()) / "kuka_iiwa" / "model.urdf"),
            basePosition=base[:3, 3].tolist(),
            baseOrientation=quaternion,
            useFixedBase=True,
            physicsClientId=self._client,
        )
        infos = [
            pybullet.getJointInfo(self._robot, j, physicsClientId=self._client)
            for j in range(pybullet.getNumJoints(self._robot, physicsClientId=self._client))
        ]
        revolute = [info for info in infos if info[2] == pybullet.JOINT_REVOLUTE]
        self.joints = [info[0] for info in revolute]
        self.lower = np.array([info[8] for info in revolute])
        self.upper = np.array([info[9] for info in revolute])
        self.velocity_limit = np.minimum([info[11] for info in revolute], max_joint_velocity)
        links = [info[12].decode() for info in infos]
        self._flange = links.index(FLANGE_LINK)
        self.world_from_base = base

    # -- lifetime ------------------------------------------------------------------------
    def close(self) -> None:
        """Disconnect the pybullet client (idempotent)."""
        if self._client is not None and self._pb.isConnected(self._client):
            self._pb.disconnect(self._client)
        self._client = None

    def __enter__(self) -> Arm:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def dof(self) -> int:
        """Number of actuated joints (7)."""
        return len(self.joints)

    # -- kinematics ----------------------------------------------------------------------
    def _set(self, q: ArrayLike) -> NDArray[np.float64]:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.dof,):
            raise ValueError(f"q must have shape ({self.dof},), got {q.shape}")
        for joint, value in zip(self.joints, q, strict=True):
            self._pb.resetJointState(self._robot, joint, value, physicsClientId=self._client)
        return q

    def flange_pose(self, q: ArrayLike) -> NDArray[np.float64]:
        """``world_from_flange`` (4x4, metres) at joint positions ``q`` (7,), radians."""
        self._set(q)
        state = self._pb.getLinkState(
            self._robot, self._flange, computeForwardKinematics=True, physicsClientId=self._client
        )
        return _pose(state[4], state[5], self._pb)  # the link frame, not its centre of mass

    def camera_pose(self, q: ArrayLike) -> NDArray[np.float64]:
        """``world_from_camera`` (4x4, metres) at joint positions ``q`` (7,)."""
        return self.flange_pose(q) @ self.hand_eye

    def camera_jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """Geometric Jacobian of the camera, expressed in the camera frame.

        Parameters
        ----------
        q : array_like, shape (7,)
            Joint positions, radians.

        Returns
        -------
        ndarray, shape (6, 7)
            Rows 0-2 map joint velocities to the linear velocity of the optical centre,
            rows 3-5 to the angular velocity, both in camera coordinates: ``(v, w) = J qdot``
            is the camera's body twist, ``d/dt world_from_camera = world_from_camera @
            [[hat(w), v], [0, 0]]``.
        """
        world_from_flange = self.flange_pose(q)  # also sets (and checks) the joints
        q = np.asarray(q, dtype=np.float64)
        # pybullet takes the point in the link frame (measured: it agrees with finite
        # differences and with pinocchio there, not at the centre-of-mass frame).
        local = self.hand_eye[:3, 3].tolist()
        zeros = [0.0] * self.dof
        linear, angular = self._pb.calculateJacobian(
            self._robot, self._flange, local, q.tolist(), zeros, zeros,
            physicsClientId=self._client,
        )
        camera_from_world = (world_from_flange[:3, :3] @ self.hand_eye[:3, :3]).T
        return np.vstack([camera_from_world @ np.asarray(linear),
                          camera_from_world @ np.asarray(angular)])

    def within_limits(self, q: ArrayLike, *, margin: float = 0.0) -> bool:
        """Whether every joint of ``q`` (7,) lies ``margin`` radians inside its limits."""
        q = np.asarray(q, dtype=np.float64)
        return bool(np.all(q >= self.lower + margin) and np.all(q <= self.upper - margin))

    def inverse_kinematics(
        self,
        world_from_camera: ArrayLike,
        *,
        rest: ArrayLike | None = None,
        margin: float = 0.0,
        position_tolerance: float = 1e-4,
        rotation_tolerance: float = 1e-3,
    ) -> NDArray[np.float64] | None:
        """Joint positions putting the camera at ``world_from_camera``, or None.

        pybullet's damped-least-squares IK with null-space limits, started from ``rest``
        (radians, the middle of the joint ranges when omitted), then checked by forward
        kinematics.

        Parameters
        ----------
        world_from_camera : array_like, shape (4, 4)
            Wanted camera pose, metres.
        rest : array_like, shape (7,), optional
            Rest posture the null space pulls towards (and the start of the search).
        margin : float
            The solution must lie this far (radians) inside every joint limit.
        position_tolerance, rotation_tolerance : float
            Largest camera position (metres) and orientation (radians) error accepted.

        Returns
        -------
        ndarray, shape (7,) or None
            None when no solution within the tolerances and limits was found.
        """
        target = np.asarray(world_from_camera, dtype=np.float64)
        flange = target @ np.linalg.inv(self.hand_eye)
        rest = 0.5 * (self.lower + self.upper) if rest is None else np.asarray(rest, float)
        pose = (flange[:3, 3].tolist(), _quaternion(flange[:3, :3]))
        self._set(rest)
        # Null-space IK near the rest posture, then plain IK from there: the null-space
        # pull leaves a residual of a few tenths of a millimetre that the second removes.
        q = self._pb.calculateInverseKinematics(
            self._robot, self._flange, *pose,
            lowerLimits=self.lower.tolist(),
            upperLimits=self.upper.tolist(),
            jointRanges=(self.upper - self.lower).tolist(),
            restPoses=rest.tolist(),
            maxNumIterations=200,
            residualThreshold=1e-6,
            physicsClientId=self._client,
        )
        self._set(q[: self.dof])
        q = self._pb.calculateInverseKinematics(
            self._robot, self._flange, *pose,
            maxNumIterations=200, residualThreshold=1e-7, physicsClientId=self._client,
        )
        q = np.asarray(q[: self.dof], dtype=np.float64)
        reached = self.camera_pose(q)
        position_error = np.linalg.norm(reached[:3, 3] - target[:3, 3])
        rotation_error = so3.rotation_angle(reached[:3, :3].T @ target[:3, :3])
        ok = position_error <= position_tolerance and rotation_error <= rotation_tolerance
        return q if ok and self.within_limits(q, margin=margin) else None


def _quaternion(rotation: NDArray[np.float64]) -> list[float]:
    """pybullet ``(x, y, z, w)`` quaternion of a rotation matrix (3, 3)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rotation).as_quat().tolist()
