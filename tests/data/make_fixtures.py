"""Write the stored scenes the tests read (``tests/scene_fixtures.py``).

Each is one instance of the seed-0 suites' generator, chosen because it shows a behaviour
a test pins (the test's docstring says which). Run from the project root, once, when a
scene is added; the files are committed and the tests never regenerate them::

    python tests/data/make_fixtures.py
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from o3d_spectral.synthetic.scenes import make_instance  # noqa: E402
from o3d_spectral.synthetic.suite import instance_rng  # noqa: E402
from tests.scene_fixtures import DATA, save_scene  # noqa: E402

#: File name: condition, object, suite seed, instance index.
SCENES = {
    "cluttered_cracker_box": ("cluttered", "cracker_box", 0, 2),
    "cluttered_power_drill": ("cluttered", "power_drill", 0, 45),
    "cluttered_tomato_soup_can": ("cluttered", "tomato_soup_can", 0, 47),
    "partial_bowl_side": ("partial", "bowl", 0, 1),
    "partial_bowl_above": ("partial", "bowl", 0, 121),
    "partial_power_drill": ("partial", "power_drill", 0, 21),
    "full_mug": ("full", "mug", 0, 198),
    "occluded_scissors": ("occluded", "scissors", 0, 154),
}


def main() -> None:
    for name, (condition, model, seed, index) in SCENES.items():
        instance = make_instance(condition, model, rng=instance_rng(seed, index))
        note = f"{condition} suite, seed {seed}, instance {index}"
        save_scene(instance, DATA / f"{name}.npz", note)
        print(f"{name}.npz: {note}, {(DATA / f'{name}.npz').stat().st_size // 1000} kB")


if __name__ == "__main__":
    main()
