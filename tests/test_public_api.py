"""The public API: the names promised at the package's top level stay importable and working."""

from __future__ import annotations

import subprocess
import sys

import pytest

import rkmpc

PUBLIC = (
    "make_controller",
    "load_scenario",
    "simulate",
    "lap_metrics",
    "TransitionDataset",
    "train_model",
    "identify",
    "KoopmanModel",
    "load_model",
)


@pytest.mark.parametrize("name", PUBLIC)
def test_public_names_import_from_the_package(name):
    value = getattr(rkmpc, name)
    assert callable(value)
    assert name in rkmpc.__all__ and name in dir(rkmpc)


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="no attribute 'warp_drive'"):
        _ = rkmpc.warp_drive  # type: ignore[attr-defined]
    assert isinstance(rkmpc.__version__, str)


def test_the_readme_example_drives_a_lap():
    from rkmpc import lap_metrics, load_scenario, make_controller, simulate
    from rkmpc.vehicle import make_plant

    sc = load_scenario("builtin")
    ctrl = make_controller("lmpc", sc.reference, sc.vehicle)
    metrics = lap_metrics(simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference))
    assert metrics["completed"] and metrics.lateral_error_mean_m < 0.05


def test_the_public_names_import_in_a_fresh_process():
    code = "from rkmpc import " + ", ".join(PUBLIC) + "; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "ok"
