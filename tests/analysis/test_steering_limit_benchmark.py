"""benchmarks/steering_limit.py: the places where a path asks for more steering than the car has."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def script(benchmark_script):
    return benchmark_script("steering_limit")


def test_the_path_wheel_angle_is_the_kinematic_one_of_the_curvature(script, builtin_scenario):
    s, wheel = script.path_wheel_angle(builtin_scenario)
    path = builtin_scenario.reference.path
    i = int(np.argmax(wheel))
    assert np.isclose(np.tan(wheel[i]), builtin_scenario.vehicle.wheelbase * abs(float(path.curvature(s[i]))))
    assert 0.1 < wheel.max() < builtin_scenario.vehicle.steering.max_angle  # the built-in track stays below


def test_the_table_names_the_tracks_whose_line_passes_the_limit(script, shared_tracks):
    tracks = ["builtin", str(shared_tracks / "centerlines" / "YasMarina.csv")]
    table = script.tracks_table(tracks, "f1tenth", 0.8).splitlines()
    rows = {line.split(" | ")[0].strip("| "): line.split(" | ") for line in table[2:]}
    assert float(rows["builtin"][3]) == 0.0
    assert float(rows["YasMarina"][3]) > 0.0  # its hairpins need more than the 0.419 rad the car has
