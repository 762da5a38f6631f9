import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.vehicle.plant import make_plant

pytest.importorskip("acados", reason="acados is the optional extra rkmpc[acados]")


def test_acados_nmpc_short_closed_loop(builtin_scenario, tmp_path, monkeypatch):
    monkeypatch.setenv("RKMPC_CACHE_DIR", str(tmp_path))
    sc = builtin_scenario
    ctrl = make_controller("nmpc-acados", sc.reference, sc.vehicle)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=4.0))
    assert result.outcome == "timeout"
    assert ctrl.fallback_count == 0
    steer = result.log["cmd_steer"][:-1]
    assert np.all(np.abs(steer) <= sc.vehicle.steering.max_angle + 1e-9)
    assert np.abs(result.log["lateral_error"]).max() < 0.3
