"""A 1:10 car composed of parts: a steering actuator, a speed loop, two tyres and a chassis.

:class:`ComposedPlant` simulates the chassis of
:mod:`rkmpc.vehicle.plants.dynamic` (same equations, see there) with any
steering actuator and speed loop of :mod:`rkmpc.vehicle.actuators` and any
tyre model of :mod:`rkmpc.vehicle.tyres`. The car zoo
(:mod:`rkmpc.vehicle.zoo`) builds its variants from it.

Integration: every internal step ``h`` the steering actuator advances first
(exactly, in its own discrete way), and the wheel angle is taken as moving
linearly from its old to its new value during that step; the chassis state
``[x, y, yaw, v, beta, yaw_rate]`` and the speed loop are then integrated with
RK4 over the step.
"""

from __future__ import annotations

from rkmpc.vehicle.actuators import SpeedLoopSpec, SteeringSpec
from rkmpc.vehicle.chassis import build_chassis
from rkmpc.vehicle.friction import FrictionSchedule
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.plants.base import SingleTrackPlant
from rkmpc.vehicle.tyres import TyreModel

__all__ = ["ComposedPlant"]


class ComposedPlant(SingleTrackPlant):
    """Single-track car assembled from a steering actuator, a speed loop and tyres.

    Parameters
    ----------
    params : VehicleParams
        The car's true chassis (mass, inertia, ``lf``, ``lr``, ``h_cg``, ``mu``,
        blending speeds) and command limits (``steering.max_angle``,
        ``drive.min_speed``, ``drive.max_speed``). Its ``steering`` time
        constant and rate, ``drive`` time constant and acceleration limits and
        tyre coefficients are NOT used: the parts below replace them.
    steering : SteeringSpec
        Steering actuator.
    speed_loop : SpeedLoopSpec
        Speed loop.
    tyre_front, tyre_rear : TyreModel
        Lateral force laws of the axles.
    internal_dt : float, optional
        Internal step (s).
    input_delay : float, optional
        Delay (s) between :meth:`step` receiving a command and the actuators
        seeing it, on top of any delay inside the steering actuator.
    friction : FrictionSchedule or None, optional
        Multiplier of ``params.mu`` in time and space.
    """

    def __init__(
        self,
        params: VehicleParams,
        *,
        steering: SteeringSpec,
        speed_loop: SpeedLoopSpec,
        tyre_front: TyreModel,
        tyre_rear: TyreModel,
        internal_dt: float = 1e-3,
        input_delay: float = 0.0,
        friction: FrictionSchedule | None = None,
    ) -> None:
        self.steering = steering
        self.speed_loop = speed_loop
        self.tyre_front = tyre_front
        self.tyre_rear = tyre_rear
        self._actuator = steering.build()
        self._accel = speed_loop.build()
        self._chassis = build_chassis(params, tyre_front.build(), tyre_rear.build())
        self._s: list[float] = [0.0] * 7
        super().__init__(params, internal_dt=internal_dt, input_delay=input_delay, friction=friction)

    def _reset_parts(self, steer: float) -> None:
        self._actuator.reset(steer)

    def _advance(self, duration: float, setpoint: tuple[float, float]) -> None:
        if duration <= 0.0:
            return
        v_cmd, d_cmd = self._clamped_setpoint(setpoint)
        mu0 = self.params.mu
        chassis, accel, actuator = self._chassis, self._accel, self._actuator
        x, y, yaw, v, beta, r, delta = self._s
        t = self._time
        for h in self._substeps(duration):
            mu = mu0 if self.friction is None else mu0 * self.friction(t, x, y)
            new_delta = actuator.advance(d_cmd, h)
            rate = (new_delta - delta) / h
            hh = 0.5 * h
            mid = delta + hh * rate
            a1 = accel(v_cmd, v)
            k1 = chassis(yaw, v, beta, r, delta, rate, a1, mu)
            v2 = v + hh * a1
            a2 = accel(v_cmd, v2)
            k2 = chassis(yaw + hh * k1[2], v2, beta + hh * k1[3], r + hh * k1[4], mid, rate, a2, mu)
            v3 = v + hh * a2
            a3 = accel(v_cmd, v3)
            k3 = chassis(yaw + hh * k2[2], v3, beta + hh * k2[3], r + hh * k2[4], mid, rate, a3, mu)
            v4 = v + h * a3
            a4 = accel(v_cmd, v4)
            k4 = chassis(yaw + h * k3[2], v4, beta + h * k3[3], r + h * k3[4], new_delta, rate, a4, mu)
            h6 = h / 6.0
            x += h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
            y += h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
            yaw += h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])
            v += h6 * (a1 + 2.0 * (a2 + a3) + a4)
            beta += h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
            r += h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
            delta = new_delta
            if v < 0.0:
                v = 0.0
            t += h
        self._s = [x, y, yaw, v, beta, r, delta]
