"""The scripts in ``examples/`` run as a user runs them and register what they say."""

from __future__ import annotations

import re
import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, capsys: pytest.CaptureFixture) -> str:
    """What ``python examples/<name>.py`` prints."""
    runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="__main__")
    return capsys.readouterr().out


def errors(output: str) -> list[tuple[float, float]]:
    """Every ``rotation error R deg, translation error T mm`` the output states."""
    found = re.findall(r"rotation error ([\d.]+) deg, translation error ([\d.]+) mm", output)
    return [(float(r), float(t)) for r, t in found]


def test_every_example_has_a_test():
    tested = {"registration_two_scans", "registration_model_in_scene",
              "registration_prepared_model", "registration_fpfh_ransac"}
    assert {p.stem for p in EXAMPLES.glob("*.py")} == tested


@pytest.mark.slow
def test_two_scans(capsys):
    (rotation, translation), = errors(run_example("registration_two_scans", capsys))
    assert rotation < 1.0 and translation < 2.0


@pytest.mark.slow
def test_model_in_scene(capsys):
    (rotation, translation), = errors(run_example("registration_model_in_scene", capsys))
    assert rotation < 5.0 and translation < 10.0


@pytest.mark.slow
def test_prepared_model_against_many_frames(capsys):
    found = errors(run_example("registration_prepared_model", capsys))
    assert len(found) == 4 and all(r < 5.0 and t < 10.0 for r, t in found)


@pytest.mark.slow
def test_comparison_with_fpfh_ransac(capsys):
    rows = [line.split() for line in run_example("registration_fpfh_ransac", capsys)
            .splitlines() if line.startswith("dragon_")]
    assert [row[1] for row in rows] == ["spectral_global", "fpfh_ransac"] * 2
    assert all(row[-1] == "True" for row in rows if row[1] == "spectral_global")
