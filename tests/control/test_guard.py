"""CommandGuard (bounds, steering-rate limit, fall-back plan) and the speed floor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rkmpc.control.guard import CommandGuard, SpeedFloor
from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.params import f1tenth

DT = 0.05
HORIZON = 4
#: A reference at rest: its speed floor is 0, so only the car's bounds apply.
V_STOP = 0.0


@pytest.fixture
def vehicle():
    return f1tenth()


@pytest.fixture
def guard(vehicle):
    return CommandGuard(vehicle, DT, HORIZON)


def _plan(n: int = HORIZON) -> np.ndarray:
    """A plan whose rows are easy to tell apart: ``[1 + k, 0.01 * k]``."""
    k = np.arange(n, dtype=float)
    return np.column_stack([1.0 + k, 0.01 * k])


def test_bounds_and_step_come_from_the_vehicle(guard, vehicle):
    assert_array_equal(guard.u_min, [vehicle.drive.min_speed, -vehicle.steering.max_angle])
    assert_array_equal(guard.u_max, [vehicle.drive.max_speed, vehicle.steering.max_angle])
    assert guard.steer_step_max == pytest.approx(vehicle.steering.max_rate * DT)
    assert guard.previous is None


def test_first_command_is_clipped_to_the_bounds_without_rate_limit(guard, vehicle):
    max_angle = vehicle.steering.max_angle
    # Far beyond one steering step (0.16 rad): no previous command, so only the angle bound applies.
    out = guard.apply(np.array([100.0, 5.0]), V_STOP)
    assert_array_equal(out, [vehicle.drive.max_speed, max_angle])
    assert out.dtype == np.float64 and out.shape == (2,)
    guard.reset()
    out = guard.apply(np.array([-3.0, -0.35]), V_STOP)
    assert_array_equal(out, [vehicle.drive.min_speed, -0.35])
    assert abs(out[1]) > guard.steer_step_max


def test_inside_the_bounds_the_command_passes_unchanged(guard):
    out = guard.apply(np.array([2.5, 0.1]), V_STOP)
    assert_array_equal(out, [2.5, 0.1])
    assert_array_equal(guard.previous, out)


def test_steering_rate_is_limited_against_the_previous_applied_command(guard):
    step = guard.steer_step_max
    guard.apply(np.array([2.0, 0.0]), V_STOP)
    out = guard.apply(np.array([2.0, 0.4]), V_STOP)
    assert out[1] == pytest.approx(step)
    # The limit is relative to the last *applied* command, not to the last requested one.
    out = guard.apply(np.array([2.0, 0.4]), V_STOP)
    assert out[1] == pytest.approx(2 * step)
    out = guard.apply(np.array([2.0, -0.4]), V_STOP)
    assert out[1] == pytest.approx(step)
    # Within one step of the previous command the request passes as is.
    out = guard.apply(np.array([2.0, step + 0.5 * step]), V_STOP)
    assert out[1] == pytest.approx(1.5 * step)
    # The speed is never rate limited.
    assert guard.apply(np.array([7.5, 1.5 * step]), V_STOP)[0] == 7.5


def test_angle_bound_applies_after_the_rate_limit(guard, vehicle):
    max_angle = vehicle.steering.max_angle
    guard.apply(np.array([1.0, max_angle]), V_STOP)
    out = guard.apply(np.array([1.0, 10.0]), V_STOP)
    assert out[1] == pytest.approx(max_angle)


def test_apply_returns_a_new_array_and_remembers_it(guard):
    u = np.array([2.0, 0.05])
    out = guard.apply(u, V_STOP)
    assert out is not u
    assert_array_equal(guard.previous, [2.0, 0.05])
    assert_array_equal(u, [2.0, 0.05])


def test_nan_stays_nan_as_with_numpy_clip(guard, vehicle):
    out = guard.apply(np.array([math.nan, 1.0]), V_STOP)
    assert math.isnan(out[0])
    assert out[1] == pytest.approx(vehicle.steering.max_angle)
    guard.reset()
    guard.apply(np.array([2.0, 0.0]), V_STOP)
    out = guard.apply(np.array([2.0, math.nan]), V_STOP)
    assert out[0] == 2.0 and math.isnan(out[1])
    # A NaN command does not poison the next finite one: it is finite and within the bounds.
    out = guard.apply(np.array([50.0, -3.0]), V_STOP)
    assert np.isfinite(out).all()
    assert_array_equal(out, [vehicle.drive.max_speed, -vehicle.steering.max_angle])


def test_accept_keeps_the_plan_and_returns_its_first_input(guard):
    plan = _plan()
    first = guard.accept(plan)
    assert_array_equal(first, plan[0])
    assert first.dtype == np.float64
    first[0] = -99.0
    assert plan[0, 0] == 1.0  # a copy, not a view of the plan
    # The stored plan is what the fall-back walks.
    assert_array_equal(guard.fallback(np.array([9.0, 9.0])), plan[1])


def test_fallback_walks_the_plan_one_step_per_call_then_returns_u_ref(guard):
    plan = _plan()
    u_ref = np.array([3.0, -0.2])
    guard.accept(plan)
    for k in range(1, HORIZON):
        assert_array_equal(guard.fallback(u_ref), plan[k])
    # The plan is now as old as the horizon: the reference input from here on.
    for _ in range(3):
        out = guard.fallback(u_ref)
        assert_array_equal(out, u_ref)
        assert out is not u_ref


def test_a_new_plan_restarts_the_fallback(guard):
    u_ref = np.array([3.0, -0.2])
    guard.accept(_plan())
    for _ in range(HORIZON + 2):
        guard.fallback(u_ref)
    plan = _plan() + 10.0
    assert_array_equal(guard.accept(plan), plan[0])
    assert_array_equal(guard.fallback(u_ref), plan[1])
    assert_array_equal(guard.fallback(u_ref), plan[2])


def test_fallback_without_a_plan_returns_u_ref_as_floats(guard):
    out = guard.fallback([1, 0])
    assert_array_equal(out, [1.0, 0.0])
    assert out.dtype == np.float64


def test_reset_forgets_plan_and_previous_command(guard):
    guard.accept(_plan())
    guard.apply(np.array([2.0, 0.0]), V_STOP)
    guard.reset()
    assert guard.previous is None
    u_ref = np.array([0.7, 0.03])
    assert_array_equal(guard.fallback(u_ref), u_ref)
    # No rate limit after a reset either.
    out = guard.apply(np.array([2.0, 0.4]), V_STOP)
    assert out[1] == pytest.approx(0.4)


# ---------------------------------------------------------------------------- speed floor


def test_speed_floor_is_half_the_reference_by_default():
    floor = SpeedFloor()
    assert_array_equal(floor.of(np.array([0.0, 1.0, 3.0])), [0.0, 0.5, 1.5])


def test_speed_floor_minimum_never_exceeds_the_reference():
    floor = SpeedFloor(fraction=0.5, minimum=0.8)
    # Slow references keep the minimum, but never more than the reference itself; zero stays zero.
    assert_array_equal(floor.of(np.array([0.0, 0.5, 1.0, 4.0])), [0.0, 0.5, 0.8, 2.0])


@pytest.mark.parametrize(
    "kwargs", [{"fraction": -0.1}, {"fraction": 1.5}, {"fraction": math.nan}, {"minimum": -1.0}]
)
def test_speed_floor_rejects_bad_settings(kwargs):
    with pytest.raises(ParameterError):
        SpeedFloor(**kwargs)


def test_apply_keeps_the_speed_at_the_floor_of_the_reference(guard):
    # A correction that would stop the car on a 1.2 m/s reference: the command keeps half of it.
    out = guard.apply(np.array([0.0, 0.1]), 1.2)
    assert out[0] == pytest.approx(0.6)
    assert out[1] == 0.1
    # Above the floor the speed passes unchanged; the floor follows the reference of the step.
    assert guard.apply(np.array([0.7, 0.1]), 1.2)[0] == 0.7
    assert guard.apply(np.array([0.7, 0.1]), 2.0)[0] == pytest.approx(1.0)


def test_apply_floor_stays_within_the_car_limits(vehicle):
    guard = CommandGuard(vehicle, DT, HORIZON, SpeedFloor(fraction=1.0))
    # A reference above the car's top speed gives a floor at the top speed, not above it.
    out = guard.apply(np.array([0.0, 0.0]), 10 * vehicle.drive.max_speed)
    assert out[0] == vehicle.drive.max_speed


def test_speed_floor_over_a_horizon_and_a_disabled_floor(vehicle):
    guard = CommandGuard(vehicle, DT, HORIZON, SpeedFloor(fraction=0.25))
    assert_allclose(guard.speed_floor(np.array([1.0, 2.0, 4.0])), [0.25, 0.5, 1.0])
    off = CommandGuard(vehicle, DT, HORIZON, SpeedFloor(fraction=0.0))
    assert off.apply(np.array([0.0, 0.0]), 2.0)[0] == vehicle.drive.min_speed
