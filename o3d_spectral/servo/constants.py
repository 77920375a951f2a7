"""Numeric constants of visual servoing (``o3d_spectral.servo``), by the module using them."""

import numpy as np

# -- servo.loop: the servoing loop ---------------------------------------------------------

#: Desired poses :func:`draw_trial` draws before giving up on finding a start.
DESIRED_POSE_ATTEMPTS = 5


# -- servo.robot: the arm ------------------------------------------------------------------

#: ``flange_from_camera`` (4x4, metres): optical centre 4 cm along the flange's x axis and
#: 10 cm along its z (tool) axis, camera axes parallel to the flange's, so the optical
#: axis is the tool axis. The lateral offset makes the camera's motion couple rotation and
#: translation, as with a real eye-in-hand sensor mounted beside the tool.
HAND_EYE = np.array(
    [
        [1.0, 0.0, 0.0, 0.04],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.10],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


# -- servo.scene: the tabletop scene -------------------------------------------------------

#: ``world_from_base`` (4x4): the iiwa's base 0.65 m behind the table's centre (x < 0), on
#: the plane of the table top.
WORLD_FROM_BASE = np.array(
    [[1.0, 0.0, 0.0, -0.65], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
