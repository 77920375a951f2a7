"""An object model found in a whole depth frame: no segmentation, no initial guess.

A YCB-Video frame (a real RGB-D capture, bundled with the package, down-sampled to
2 mm) holds several objects on a table; the gelatin box's model is registered into the
whole frame. The global search finds where in the scene the model fits, then polishes the
pose; the result is compared with the dataset's annotated pose, up to the box's
symmetries (a box turned half a turn fits its view as well).

Run: ``python examples/registration_model_in_scene.py``
"""

import time

import numpy as np
import open3d as o3d

import o3d_spectral
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.harness.real import real_dir, ycbv_symmetry

VOXEL_SIZE = 0.008  # metres
OBJECT = "009_gelatin_box"


def main() -> None:
    ycbv = real_dir() / "ycbv"
    model = o3d.io.read_point_cloud(str(ycbv / "models" / f"{OBJECT}.ply"))
    scene = o3d.io.read_point_cloud(str(ycbv / "0000_000001" / "scene_2mm.ply"))
    truth = np.loadtxt(ycbv / "0000_000001" / f"{OBJECT}_T_cam_from_model.txt").reshape(4, 4)
    print(f"model: {len(model.points)} points, scene: {len(scene.points)} points")

    start = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(model, scene, VOXEL_SIZE)
    seconds = time.perf_counter() - start

    symmetry, center = ycbv_symmetry(OBJECT), model.get_center()
    error_deg = symmetric_rotation_error(result.transformation, truth, symmetry)
    error_mm = 1000 * symmetric_translation_error(result.transformation, truth, symmetry,
                                                  center=center)
    print(result)
    print("Transformation:\n", result.transformation)
    print("stages (s):", {stage: round(t, 2) for stage, t in result.stage_times.items()})
    print(f"{seconds:.1f} s; rotation error {error_deg:.2f} deg, "
          f"translation error {error_mm:.1f} mm (up to the box's symmetries)")


if __name__ == "__main__":
    main()
