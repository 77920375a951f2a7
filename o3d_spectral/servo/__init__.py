"""Direct 3D visual servoing of a simulated KUKA LBR iiwa (paper, section 5).

An eye-in-hand depth camera on pybullet's iiwa model is driven from a random pose to the
pose where a reference cloud of a static tabletop was captured, by the spectral control
law on whole-scene clouds (no segmentation, no correspondences)::

    from o3d_spectral import servo
    with servo.Arm(world_from_base=servo.WORLD_FROM_BASE) as arm:
        trial = servo.random_trial(0, arm, servo.Sensor())
    print(trial.run.final.translation_error, trial.run.converged)

One module per part: ``law`` (one control cycle: global search, then the paper's
law; needs no simulator), ``robot`` (the arm and hand-eye transform), ``scene`` (tabletop,
sensor, start poses), ``control`` (twist, damped pseudo-inverse, limits), ``loop`` (the
paper's Algorithm 1), ``figures``. Needs the ``servo`` extra (pybullet); see
``docs/servo.md``.
"""

from .control import camera_twist, damped_pseudo_inverse, joint_velocities, limit_velocities
from .law import ServoLaw, Step
from .loop import (
    Cycle,
    ServoOptions,
    ServoRun,
    Trial,
    draw_trial,
    pose_errors,
    random_trial,
    servo,
)
from .robot import HAND_EYE, Arm
from .scene import (
    WORLD_FROM_BASE,
    Sensor,
    Start,
    Tabletop,
    desired_pose,
    make_tabletop,
    sample_start,
)

__all__ = [
    "ServoLaw",
    "Step",
    "Arm",
    "HAND_EYE",
    "WORLD_FROM_BASE",
    "Sensor",
    "Start",
    "Tabletop",
    "make_tabletop",
    "desired_pose",
    "sample_start",
    "camera_twist",
    "damped_pseudo_inverse",
    "joint_velocities",
    "limit_velocities",
    "ServoOptions",
    "Cycle",
    "ServoRun",
    "Trial",
    "pose_errors",
    "servo",
    "random_trial",
    "draw_trial",
]
