"""Two scans of one object, in any relative orientation: the global search.

Two range scans of the Stanford dragon taken 24 degrees apart on a turntable (bundled
with the package), each missing what the other sees. The source is first turned by a
large rotation so that no initial guess helps; ``registration_spectral_global`` searches
all rotations (no features, no correspondences) and the result is compared with the
turntable's ground truth.

Run: ``python examples/registration_two_scans.py``
"""

import time

import numpy as np
import open3d as o3d

import o3d_spectral
from o3d_spectral.common.pose_errors import rotation_error, translation_error
from o3d_spectral.harness.real import dragon_pose, real_dir

VOXEL_SIZE = 0.005  # metres: the dragon is about 20 cm long


def load_scan(angle: int) -> o3d.geometry.PointCloud:
    """The dragon scan taken at ``angle`` degrees, in its scanner's frame (metres)."""
    return o3d.io.read_point_cloud(str(real_dir() / "dragon" / f"dragonStandRight_{angle}.ply"))


def main() -> None:
    source, target = load_scan(0), load_scan(24)
    truth = np.linalg.inv(dragon_pose(24)) @ dragon_pose(0)  # source -> target

    # Turn the source by 120 degrees about its centroid: the registration must find it.
    turn = np.eye(4)
    turn[:3, :3] = o3d.geometry.get_rotation_matrix_from_axis_angle([0.0, 2.1, 0.0])
    centroid = source.get_center()
    turn[:3, 3] = centroid - turn[:3, :3] @ centroid
    source.transform(turn)
    truth = truth @ np.linalg.inv(turn)

    start = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL_SIZE)
    seconds = time.perf_counter() - start

    print(result)
    print("Transformation:\n", result.transformation)
    print(f"confidence {result.confidence:.3f}, {seconds:.1f} s")
    error_mm = 1000 * translation_error(result.transformation, truth, center=centroid)
    print(f"rotation error {rotation_error(result.transformation, truth):.2f} deg, "
          f"translation error {error_mm:.2f} mm")


if __name__ == "__main__":
    main()
