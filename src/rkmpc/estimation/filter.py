"""The state a controller needs from what a real car measures: an extended Kalman filter.

:class:`StateEstimator` fuses the localiser's pose (late, irregular, with jumps), the wheel
speed (noisy, mis-scaled) and the gyro (noisy, biased) on the single-track model of
:mod:`rkmpc.estimation.model`, with the front wheel angle propagated from the commands sent
through a :class:`~rkmpc.estimation.steering.SteeringModel`. Each :meth:`StateEstimator.update`
predicts to the observation's time, then fuses, in this order, a new pose, the wheel speed and
the gyro (one update of the two), and a measured slip angle, each only when finite and each
behind its own chi-square gate (:mod:`rkmpc.estimation.kalman` has the algebra).

What each estimate rests on
---------------------------
* Pose: the localiser, extrapolated over its latency (``time - pose_time``) along the estimated
  velocities; between poses, dead reckoning on speed and yaw rate.
* Speed ``vx``: the wheel speed divided by the estimated sensor scale; the scale is observable
  because the poses measure the distance driven (it settles over some seconds of driving).
* Yaw rate: the gyro less its estimated bias (the bias is observable from the poses' heading).
* Slip angle ``atan(vy / |vx|)``: weakly observable. The pose measures the course (direction of
  travel) only through position differences, good to about ``position_std / (v T)`` rad over
  ``T`` seconds: at 5 cm and 3 m/s some 0.05 rad over 0.3 s, the size of a 1:10 car's slip
  itself. The estimate therefore rests mostly on the model: the rear axle's steady slip for the
  measured yaw rate and speed (linear tyre, the car's cornering stiffness), corrected by the
  poses where they disagree for long. Expect its sign and size in steady cornering, not its
  transients, and an error that grows where the rear tyres saturate.
* Wheel angle: the steering model's response to the commands, or the measurement where the car
  has one (the model then continues from it).

Robustness
----------
A pose whose innovation lies beyond the gate is rejected and counted (a jump of the
localiser); ``max_rejections`` rejections of one sensor in a row re-initialise the part of the
state it measures from it, counted too. A pose that did not change (same ``pose_time`` or the
same values) is no measurement; an older one than the last used, or one
older than ``max_latency``, is not used. A gap longer than ``max_gap``, a time going backwards or
a state turned non-finite restarts the filter from the observation; the first pose after more
than ``max_gap`` without one restarts the pose from it (counted as a gap restart).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.stats import chi2

from rkmpc.core.angles import wrap_scalar
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.diagnostics import EstimatorCounts, EstimatorDiagnostics, FilterStep
from rkmpc.estimation.kalman import apply, apply_one, cholesky2, cholesky3
from rkmpc.estimation.model import BIAS, N_STATES, SCALE, VX, VY, YAW, R, SingleTrackModel, X, Y, slip_of
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator
from rkmpc.vehicle.params import VehicleParams

__all__ = ["StateEstimator"]

#: Updates between two symmetrisations of the covariance.
_SYMMETRISE_EVERY = 64


class StateEstimator:
    """An EKF for a car with a pose localiser, a wheel-speed sensor and a gyro (see the module notes).

    Parameters
    ----------
    vehicle : VehicleParams
        The car (geometry, mass and tyres of the process model).
    config : EstimatorConfig, optional
        Tuning (:class:`EstimatorConfig` defaults).
    steering : SteeringModel, optional
        The servo the wheel angle is propagated through (the car's nominal one by default).
    """

    def __init__(
        self,
        vehicle: VehicleParams,
        config: EstimatorConfig | None = None,
        steering: SteeringModel | None = None,
    ) -> None:
        self.vehicle = vehicle
        self.config = config if config is not None else EstimatorConfig()
        self.steering = steering if steering is not None else SteeringModel.nominal(vehicle)
        cfg = self.config
        self.model = SingleTrackModel(vehicle, cfg)
        self._wheel = WheelAnglePropagator(self.steering, cfg.control_period)
        self._gate1 = float(chi2.ppf(cfg.gate_probability, 1))
        self._gate3 = float(chi2.ppf(cfg.gate_probability, 3))
        self._pose_var = (cfg.position_std**2, cfg.position_std**2, cfg.yaw_std**2)
        self._pose_density = (cfg.position_density**2, cfg.position_density**2, cfg.yaw_density**2)
        self._speed_var = cfg.speed_std**2
        self._gyro_var = cfg.yaw_rate_std**2
        self._slip_var = cfg.slip_std**2
        self._p0 = [s * s for s in cfg.initial_stds()]
        self._identity = np.eye(N_STATES)
        self._zeros = np.zeros((N_STATES, N_STATES))
        # Measurement rows and transposed inverse Cholesky factors, filled in place each update:
        # the wheel speed (k vx) and the gyro (r + b), the slip angle, the pose's 3x3 factor.
        self._motion_rows = np.zeros((2, N_STATES))
        self._motion_rows[1, R] = self._motion_rows[1, BIAS] = 1.0
        self._motion_d = np.zeros((2, 2))
        self._slip_row = np.zeros(N_STATES)
        self._pose_d = np.zeros((3, 3))
        self.reset()

    def reset(self) -> None:
        """Forget the state, the commands and the counts."""
        self._x = np.zeros(N_STATES)
        self._P = np.diag(self._p0)
        self._initialised = False
        self._time = math.nan
        self._delta = math.nan
        self._last_pose = (math.nan, math.nan, math.nan)
        self._last_pose_time = -math.inf
        self._pose_used_at = -math.inf
        self._streak = {"pose": 0, "speed": 0, "yaw_rate": 0, "slip": 0}
        self._counts = EstimatorCounts()
        self._wheel.reset()
        self._started = False
        self._F = self._identity
        self._Q = self._zeros
        self._x_prior = self._x
        self._P_prior = self._P

    @property
    def initialised(self) -> bool:
        """Whether the filter has a state (it needs one finite pose)."""
        return self._initialised

    def diagnostics(self) -> EstimatorDiagnostics:
        """Counts since :meth:`reset` and the sensor estimates (scale, bias)."""
        return self._counts.record(float(self._x[SCALE]), float(self._x[BIAS]))

    def last_step(self) -> FilterStep:
        """The last update's prediction and estimate (copies), for a smoother."""
        return FilterStep(
            started=self._started,
            transition=self._F.copy(),
            noise=self._Q.copy(),
            prior_state=self._x_prior.copy(),
            prior_covariance=self._P_prior.copy(),
            state=self._x.copy(),
            covariance=self._P.copy(),
            wheel_angle=self._delta,
        )

    def update(self, observation: Observation, command_sent_last: Command | None) -> Observation:
        """The estimate at ``observation.time`` from this raw observation; never raises on NaN.

        Parameters
        ----------
        observation : Observation
            What the sensors report; NaN fields are not measured, ``pose_time`` says how old the
            pose is (NaN: current; unchanged: no new pose).
        command_sent_last : Command or None
            The command sent at the previous control period (None before the first).

        Returns
        -------
        Observation
            Pose (m, m, rad), speed ``vx`` (m/s), yaw rate (rad/s), slip angle (rad) and wheel
            angle (rad) at ``observation.time``, ``pose_time`` NaN. Before the first finite pose,
            the observation itself with the wheel angle filled in.
        """
        self._counts.updates += 1
        steer = None if command_sent_last is None else float(command_sent_last.steer)
        measured_steer = observation.steer_angle
        delta_before = self._delta
        delta = self._wheel.step(steer, measured_steer if math.isfinite(measured_steer) else math.nan)
        self._delta = delta
        t = float(observation.time)
        self._started = False
        if self._initialised:
            dt = t - self._time
            if not dt >= 0.0:
                self._counts.restarts_time += 1
                self._initialised = False
            elif dt > self.config.max_gap:
                self._counts.restarts_gap += 1
                self._initialised = False
        if not self._initialised:
            if not self._initialise(observation, t, delta):
                return replace(observation, steer_angle=delta)
            return self._estimate(t, delta)
        if dt > 0.0:
            self._predict(dt, 0.5 * (delta_before + delta))
        else:
            self._F, self._Q = self._identity, self._zeros
            self._x_prior, self._P_prior = self._x, self._P
        self._fuse(observation, t)
        self._time = t
        x, y, yaw, vx, vy, r, k, b = self._x.tolist()
        if math.isfinite(x + y + yaw + vx + vy + r + k + b):
            return Observation(x, y, yaw, vx, r, slip_of(vx, vy), delta, t)
        self._counts.restarts_diverged += 1
        self._initialised = False
        if not self._initialise(observation, t, delta):
            return replace(observation, steer_angle=delta)
        return self._estimate(t, delta)

    # ------------------------------------------------------------------ steps

    def _estimate(self, t: float, delta: float) -> Observation:
        x, y, yaw, vx, vy, r, _, _ = self._x.tolist()
        return Observation(x, y, yaw, vx, r, slip_of(vx, vy), delta, t)

    def _initialise(self, obs: Observation, t: float, delta: float) -> bool:
        """Start from the observation's pose; False when it has none."""
        if not (math.isfinite(obs.x) and math.isfinite(obs.y) and math.isfinite(obs.yaw)):
            return False
        model = self.model
        vx = obs.speed if math.isfinite(obs.speed) else 0.0
        r = obs.yaw_rate if math.isfinite(obs.yaw_rate) else model.steady_yaw_rate(vx, delta)
        vy = vx * math.tan(obs.slip_angle) if math.isfinite(obs.slip_angle) else model.lateral_gain(vx) * r
        lag = t - obs.pose_time if math.isfinite(obs.pose_time) else 0.0
        lag = min(max(lag, 0.0), self.config.max_latency)
        c, s = math.cos(obs.yaw), math.sin(obs.yaw)
        x, y = obs.x + lag * (vx * c - vy * s), obs.y + lag * (vx * s + vy * c)
        self._x = np.array((x, y, obs.yaw + lag * r, vx, vy, r, 1.0, 0.0))
        self._P = np.diag(self._p0)
        self._last_pose = (obs.x, obs.y, obs.yaw)
        self._last_pose_time = obs.pose_time if math.isfinite(obs.pose_time) else -math.inf
        self._pose_used_at = t - lag
        self._streak = dict.fromkeys(self._streak, 0)
        self._counts.used["pose"] += 1
        self._time = t
        self._initialised = True
        self._started = True
        self._F, self._Q = self._identity, self._zeros
        self._x_prior, self._P_prior = self._x, self._P
        return True

    def _predict(self, dt: float, delta: float) -> None:
        # Every later change makes new arrays (no in-place updates), so the prior stays as it is.
        model = self.model
        self._x = self._x_prior = np.array(model.transition(self._x.tolist(), dt, delta))
        F = model.F
        Q = model.process_noise(dt)
        P = F.dot(self._P).dot(F.T) + Q
        if self._counts.updates % _SYMMETRISE_EVERY == 0:
            # F P F^T is symmetric up to rounding only (the updates are exactly symmetric).
            P = (P + P.T) * 0.5
        self._P = self._P_prior = P
        self._F, self._Q = F, Q

    def _fuse(self, obs: Observation, t: float) -> None:
        px, py, pyaw = obs.x, obs.y, obs.yaw
        counts = self._counts
        if math.isfinite(px) and math.isfinite(py) and math.isfinite(pyaw):
            pose_time = obs.pose_time
            # The same values (a pose held between localiser updates, whatever its time) or the
            # same sample time: no new pose.
            if (px, py, pyaw) == self._last_pose or pose_time == self._last_pose_time:
                counts.poses_repeated += 1
            elif not math.isfinite(pose_time):
                self._last_pose = (px, py, pyaw)
                self._new_pose(px, py, pyaw, 0.0, t)
            elif pose_time < self._last_pose_time or t - pose_time > self.config.max_latency:
                counts.poses_too_old += 1
                self._last_pose_time = max(self._last_pose_time, pose_time)
            else:
                self._last_pose_time = pose_time
                self._last_pose = (px, py, pyaw)
                self._new_pose(px, py, pyaw, max(t - pose_time, 0.0), t)
        if math.isfinite(obs.speed) or math.isfinite(obs.yaw_rate):
            self._motion_update(obs.speed, obs.yaw_rate)
        vx, vy = float(self._x[VX]), float(self._x[VY])
        if math.isfinite(obs.slip_angle) and vx > self.config.min_slip_speed:
            self._slip_update(wrap_scalar(obs.slip_angle - math.atan2(vy, vx)), vx, vy)

    def _new_pose(self, px: float, py: float, pyaw: float, lag: float, t: float) -> None:
        """Fuse a new pose; after more than ``max_gap`` without one, start the pose afresh from it."""
        if t - lag - self._pose_used_at > self.config.max_gap:
            # Dead-reckoned that long, the pose's linearised covariance means nothing (the heading
            # may have turned around): the gate would judge the localiser by a meaningless ellipse.
            self._counts.restarts_gap += 1
            h, _ = self.model.pose(self._x.tolist(), lag)
            nu = (px - h[0], py - h[1], wrap_scalar(pyaw - h[2]))
            self._reinitialise(((X, nu[0]), (Y, nu[1]), (YAW, nu[2])))
            self._counts.used["pose"] += 1
            self._pose_used_at = t - lag
            return
        if self._pose_update(px, py, pyaw, lag):
            self._pose_used_at = t - lag

    def _motion_update(self, speed: float, yaw_rate: float) -> None:
        """The wheel speed ``k vx`` and the gyro ``r + b`` (NaN: not measured), each behind its 1-dof gate.

        Both accepted: one 2-row update; one: a scalar update.
        """
        _, _, _, vx, _, r, k, b = self._x.tolist()
        H = self._motion_rows
        H[0, VX], H[0, SCALE] = k, vx
        pht = self._P.dot(H.T)
        (s00, s01), (_, s11) = H.dot(pht).tolist()
        s00 += self._speed_var
        s11 += self._gyro_var
        n0, n1 = speed - k * vx, yaw_rate - r - b
        gate = self._gate1
        take0 = n0 * n0 <= gate * s00  # False for NaN: not measured
        take1 = n1 * n1 <= gate * s11
        factor = cholesky2(s00, s01, s11)
        if factor is None:
            self._x = self._x * math.nan  # a covariance no longer positive: restart the filter
            return
        if take0 and take1:
            c00, c10, c11 = factor
            u0 = n0 / c00
            inverse_t = self._motion_d
            inverse_t[0, 0], inverse_t[0, 1], inverse_t[1, 1] = 1.0 / c00, -c10 / (c00 * c11), 1.0 / c11
            self._x, self._P = apply(self._x, self._P, pht, inverse_t, (u0, (n1 - c10 * u0) / c11))
        elif take0:
            self._x, self._P = apply_one(self._x, self._P, pht[:, 0], s00, n0)
        elif take1:
            self._x, self._P = apply_one(self._x, self._P, pht[:, 1], s11, n1)
        for sensor, taken, nu, shift in (
            ("speed", take0, n0, (VX, n0 / max(k, 1e-3))),
            ("yaw_rate", take1, n1, (R, n1)),
        ):
            if taken:
                self._streak[sensor] = 0
                self._counts.used[sensor] += 1
            elif math.isfinite(nu):
                self._rejected(sensor, (shift,))

    def _slip_update(self, innovation: float, vx: float, vy: float) -> None:
        """A measured slip angle ``atan2(vy, vx)``, behind its 1-dof gate."""
        norm = vx * vx + vy * vy
        h = self._slip_row
        h[VY], h[VX] = vx / norm, -vy / norm
        pht = self._P.dot(h)
        s = vx / norm * float(pht[VY]) - vy / norm * float(pht[VX]) + self._slip_var
        if innovation * innovation > self._gate1 * s:
            self._rejected("slip", ((VY, innovation * norm / vx),))
            return
        self._streak["slip"] = 0
        self._counts.used["slip"] += 1
        self._x, self._P = apply_one(self._x, self._P, pht, s, innovation)

    def _pose_update(self, px: float, py: float, pyaw: float, lag: float) -> bool:
        """The 3-dof pose update behind the 3-dof gate (False: rejected); the noise grows with the lag."""
        h, H = self.model.pose(self._x.tolist(), lag)
        n0, n1, n2 = px - h[0], py - h[1], wrap_scalar(pyaw - h[2])
        pht = self._P.dot(H.T)
        (a, b, c), (_, d, e), (_, _, f) = H.dot(pht).tolist()
        var, dens = self._pose_var, self._pose_density
        factor = cholesky3(
            a + var[0] + lag * dens[0], b, c, d + var[1] + lag * dens[1], e, f + var[2] + lag * dens[2]
        )
        if factor is None:
            self._x = self._x * math.nan  # a covariance no longer positive: restart the filter
            return False
        c00, c10, c20, c11, c21, c22 = factor
        u0 = n0 / c00
        u1 = (n1 - c10 * u0) / c11
        u2 = (n2 - c20 * u0 - c21 * u1) / c22
        if not u0 * u0 + u1 * u1 + u2 * u2 <= self._gate3:
            return self._rejected("pose", ((X, n0), (Y, n1), (YAW, n2)))
        self._streak["pose"] = 0
        self._counts.used["pose"] += 1
        # D = C^-1 (lower triangular), stored transposed.
        d00, d11, d22 = 1.0 / c00, 1.0 / c11, 1.0 / c22
        d10 = -c10 * d00 * d11
        inverse_t = self._pose_d
        inverse_t[0, 0], inverse_t[0, 1], inverse_t[0, 2] = d00, d10, -(c20 * d00 + c21 * d10) * d22
        inverse_t[1, 1], inverse_t[1, 2], inverse_t[2, 2] = d11, -c21 * d11 * d22, d22
        self._x, self._P = apply(self._x, self._P, pht, inverse_t, (u0, u1, u2))
        return True

    # ------------------------------------------------------------------ rejections

    def _rejected(self, sensor: str, shift: tuple[tuple[int, float], ...]) -> bool:
        """Count a gated measurement; after ``max_rejections`` in a row, take the sensor's word.

        ``shift`` holds ``(state index, change)`` pairs that make the prediction match the
        measurement (to first order). Returns whether the measurement was taken after all.
        """
        self._counts.rejected[sensor] += 1
        self._streak[sensor] += 1
        if self._streak[sensor] < self.config.max_rejections:
            return False
        self._streak[sensor] = 0
        self._counts.reinitialised[sensor] += 1
        self._reinitialise(shift)
        return True

    def _reinitialise(self, shift: tuple[tuple[int, float], ...]) -> None:
        """Move the states of ``shift`` by its changes; they restart with their initial variance."""
        self._started = True
        self._x = self._x.copy()
        P = self._P = self._P.copy()
        for index, change in shift:
            self._x[index] += change
            P[index, :] = 0.0
            P[:, index] = 0.0
        for index, _ in shift:
            P[index, index] = self._p0[index]
