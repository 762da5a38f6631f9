"""benchmarks/steering_limit.py: the places where a path asks for more steering than the car has."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "steering_limit.py"


def _script():
    spec = importlib.util.spec_from_file_location("steering_limit", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_path_wheel_angle_is_the_kinematic_one_of_the_curvature(builtin_scenario):
    s, wheel = _script().path_wheel_angle(builtin_scenario)
    path = builtin_scenario.reference.path
    i = int(np.argmax(wheel))
    assert np.isclose(np.tan(wheel[i]), builtin_scenario.vehicle.wheelbase * abs(float(path.curvature(s[i]))))
    assert 0.1 < wheel.max() < builtin_scenario.vehicle.steering.max_angle  # the built-in track stays below


def test_the_table_names_the_tracks_whose_line_passes_the_limit(shared_tracks):
    table = (
        _script()
        .tracks_table(["builtin", str(shared_tracks / "centerlines" / "YasMarina.csv")], "f1tenth", 0.8)
        .splitlines()
    )
    rows = {line.split(" | ")[0].strip("| "): line.split(" | ") for line in table[2:]}
    assert float(rows["builtin"][3]) == 0.0
    assert float(rows["YasMarina"][3]) > 0.0  # its hairpins need more than the 0.419 rad the car has
