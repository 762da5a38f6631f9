"""Through the slowest corner of every shared track: no MPC parks the car (the speed floor).

The residual MPC of ``rkmpc-paper`` may correct the LMPC's speed by up to 1 m/s; in a corner with a
reference of about 1 m/s (0.5 m/s on the 1:10 tracks) that correction stopped the car for good.
Each run starts a metre before the arc length of the lowest reference speed and drives 100 steps
(5 s): the car must stay on the track, pass that point, and command at least about half the
reference speed at every step.
"""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.control.guard import SpeedFloor
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.settings import ControllerSettings
from rkmpc.sim.closed_loop import SimConfig, SimResult, simulate
from rkmpc.sim.scenario import load_scenario
from rkmpc.vehicle.registry import make_plant

TRACKS = (
    "Austin", "Budapest", "Catalunya", "Hockenheim", "IMS", "Melbourne", "MexicoCity", "Montreal",
    "Monza", "MoscowRaceway", "Nuerburgring", "Oschersleben", "Sakhir", "SaoPaulo", "Sepang",
    "Shanghai", "Silverstone", "Spielberg", "YasMarina",
)  # fmt: skip
#: Tracks driven in the fast tier: without the floor, rkmpc-paper parks in each of them.
FAST = ("Catalunya", "Melbourne", "Monza")
#: Start before the slowest point (m) and steps driven.
BEFORE, STEPS = 1.0, 100
#: Share of the reference speed the command keeps (the floor is half; the simulator's projection
#: of the car, which sets the logged reference, may differ slightly from the controller's).
KEEPS = 0.45


def _scenario(shared_tracks, track):
    return load_scenario(shared_tracks / "centerlines" / f"{track}.csv")


def _slowest(scenario) -> float:
    """Arc length of the lowest reference speed (m)."""
    s = np.linspace(0.0, scenario.reference.path.length, 4000, endpoint=False)
    return float(s[np.argmin(scenario.reference.profile.speed(s))])


def _drive(scenario, name, **options) -> SimResult:
    ctrl = make_controller(name, scenario.reference, scenario.vehicle, **options)
    start = (_slowest(scenario) - BEFORE) % scenario.reference.path.length
    config = SimConfig(dt=scenario.dt, start_s=start, max_time=(STEPS - 0.5) * scenario.dt)
    return simulate(make_plant("f1tenth"), ctrl, scenario.track, scenario.reference, config)


@pytest.mark.parametrize(
    "track", [t if t in FAST else pytest.param(t, marks=pytest.mark.slow) for t in TRACKS]
)
@pytest.mark.parametrize("name", ["lmpc", "rkmpc-paper"])
def test_the_car_drives_through_the_slowest_corner(shared_tracks, small_paper_model, track, name):
    scenario = _scenario(shared_tracks, track)
    options = {"model": small_paper_model} if name == "rkmpc-paper" else {}
    result = _drive(scenario, name, **options)
    log = result.log
    assert result.outcome == "timeout", (track, result.outcome)
    # It passed the slowest point, and never asked for less than (about) half the reference.
    assert result.progress * result.lap_length > BEFORE + 0.25
    ratio = np.asarray(log["cmd_speed"]) / np.asarray(log["v_r"])
    assert np.nanmin(ratio) >= KEEPS, (track, float(np.nanmin(ratio)))


def test_without_the_floor_rkmpc_paper_parks_in_the_corner(shared_tracks, small_paper_model):
    # What the floor prevents: the correction cancels the reference and the car stops before the corner.
    scenario = _scenario(shared_tracks, "Catalunya")
    off = LMPCConfig(speed_floor=SpeedFloor(fraction=0.0))
    result = _drive(scenario, "rkmpc-paper", model=small_paper_model, settings=ControllerSettings(lmpc=off))
    assert float(np.min(result.log["speed"][-20:])) < 0.05
    assert result.progress * result.lap_length < BEFORE + 0.25
