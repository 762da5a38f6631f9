"""Every MPC keeps its speed command at or above the floor tied to the reference (learned ones too)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.control.guard import SpeedFloor
from rkmpc.control.learned.residual_config import ResidualMPCConfig
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.nonlinear.nlp import NMPCConfig
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.learning.identification import IdentifiedModel

S0 = 5.0
#: Makes the MPC hold the command it applied before (0 m/s: the car at rest), whatever the reference.
HOLD = {"speed_weight": 1e-3, "speed_rate_weight": 1e3}
OFF = SpeedFloor(fraction=0.0)


class _LinearModel:
    """A lifted model ``z+ = z + B u`` on the recipe's features, ``y = z`` (no lifting)."""

    def __init__(self, nx: int, B: np.ndarray) -> None:
        self.A_ = np.eye(nx)
        self.B_ = B
        self.C_ = np.eye(nx)
        self.D_ = np.zeros((nx, B.shape[1]))

    def lift(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(X, dtype=float)


def _backwards(nx: int) -> _LinearModel:
    """A wrong model: the slower the command, the farther the car goes (it would stop to follow)."""
    B = np.zeros((nx, 2))
    B[0, 0] = -0.005
    return _LinearModel(nx, B)


def _observation(scenario, speed: float) -> Observation:
    path = scenario.reference.path
    p = path.position(S0)
    return Observation(
        x=float(p[0]), y=float(p[1]), yaw=float(path.heading(S0)), speed=speed, yaw_rate=0.0, steer_angle=0.0
    )


def _first_speed(scenario, name: str, speed: float = 0.0, **options) -> tuple[float, float]:
    """The first speed command of a controller on the path at ``S0`` and the reference speed there."""
    ctrl = make_controller(name, scenario.reference, scenario.vehicle, **options)
    command = ctrl.step(_observation(scenario, speed))
    v_ref = float(scenario.reference.profile.speed(S0))
    return command.speed, v_ref


def _holding(name: str, floor: SpeedFloor | None) -> dict:
    """Options under which ``name`` wants to hold 0 m/s, with the given floor (None: the default)."""
    extra = {} if floor is None else {"speed_floor": floor}
    if name.startswith("nmpc"):
        settings = ControllerSettings(nmpc=NMPCConfig(**HOLD, **extra))
    else:
        settings = ControllerSettings(lmpc=LMPCConfig(**HOLD, **extra))
    options: dict = {"settings": settings}
    if name == "lmpc-id":
        options["model"] = IdentifiedModel(0.158, 0.005, 1.0, 1.0, 100)
    if name == "kmpc":
        options["model"] = _LinearModel(6, np.zeros((6, 2)))
    return options


@pytest.mark.parametrize("name", ["lmpc", "lmpc-id", "kmpc", "nmpc", "nmpc-dynamic"])
def test_an_mpc_that_would_stay_at_rest_commands_the_floor(builtin_scenario, name):
    # Without the floor the MPC holds the car at rest; with it, the command is half the reference.
    held, v_ref = _first_speed(builtin_scenario, name, **_holding(name, OFF))
    assert held < 0.05 * v_ref
    floored, _ = _first_speed(builtin_scenario, name, **_holding(name, None))
    assert floored == pytest.approx(0.5 * v_ref, rel=1e-6)


def test_a_learned_correction_that_cancels_the_reference_stops_at_the_floor(builtin_scenario):
    sc = builtin_scenario
    v_ref = float(sc.reference.profile.speed(S0))
    model = _backwards(3)
    # Corrections as large as the reference, weighted next to nothing: the QP wants to stop the car.
    config = ResidualMPCConfig(speed_weight=1e-6, steer_weight=1e3, max_speed_correction=2 * v_ref)
    off = make_controller(
        "rkmpc-paper",
        sc.reference,
        sc.vehicle,
        model=model,
        settings=ControllerSettings(rkmpc_paper=config, lmpc=LMPCConfig(speed_floor=OFF)),
    )
    assert off.step(_observation(sc, v_ref)).speed == pytest.approx(sc.vehicle.drive.min_speed, abs=1e-9)
    ctrl = make_controller(
        "rkmpc-paper", sc.reference, sc.vehicle, model=model, settings=ControllerSettings(rkmpc_paper=config)
    )
    speeds = []
    for _ in range(5):
        command = ctrl.step(_observation(sc, v_ref))
        assert ctrl.info.status == "ok"
        speeds.append(command.speed)
    # The correction is as negative as the floor allows, every step, and the QP planned with it.
    assert speeds == pytest.approx([0.5 * ctrl.lmpc.reference_speed] * 5, rel=1e-9)
    assert ctrl.last_correction[0] < -0.4 * v_ref


def test_kmpc_with_a_model_that_would_stop_the_car_commands_the_floor(builtin_scenario):
    sc = builtin_scenario
    speed, v_ref = _first_speed(sc, "kmpc", speed=3.0, model=_backwards(6))
    assert speed == pytest.approx(0.5 * v_ref, rel=1e-6)
    unfloored, _ = _first_speed(
        sc,
        "kmpc",
        speed=3.0,
        model=_backwards(6),
        settings=ControllerSettings(lmpc=LMPCConfig(speed_floor=OFF)),
    )
    assert unfloored < 0.1 * v_ref


def test_the_floor_is_a_validated_setting(builtin_scenario):
    assert LMPCConfig().speed_floor == SpeedFloor(fraction=0.5, minimum=0.0)
    with pytest.raises(ParameterError, match="speed_floor"):
        LMPCConfig(speed_floor=0.5)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="fraction"):
        NMPCConfig(speed_floor=SpeedFloor(fraction=2.0))
    ctrl = make_controller("lmpc", builtin_scenario.reference, builtin_scenario.vehicle)
    assert math.isnan(ctrl.reference_speed)
    ctrl.step(_observation(builtin_scenario, 1.0))
    assert ctrl.reference_speed == pytest.approx(
        float(builtin_scenario.reference.profile.speed(S0)), rel=1e-3
    )
