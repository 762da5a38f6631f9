"""Named sensor profiles (:data:`SENSOR_PROFILES`, :func:`get_sensor_profile`) and what they rest on.

``ideal``
    Today's simulator: every field true and current (the plant is not wrapped).
``no-steer``
    The true pose, speed and yaw rate, but no wheel angle and no side-slip
    (NaN): what the F1TENTH gym's default observation gives. Separates the
    effect of the missing sensors from that of the noise.
``f1tenth-real``
    A real F1TENTH car: the pose from a particle filter on a lidar map, the
    speed from the VESC motor controller, the yaw rate from the VESC's IMU; no
    steering-angle sensor and no lateral velocity. Its numbers were measured on
    the two shared runs of a real car (``../shared/real/f1tenth-car``: DS2, 159 s
    at up to 5 m/s; DS3, 127 s at about 1.3 m/s), as follows.

Measured on the real logs, and the values chosen
-------------------------------------------------
Pose rate (intervals between particle-filter stamps, gaps over 0.5 s left
out): DS2 mean 28.3 ms (35 Hz), median 23.9 ms, 5-95 % 17.3-46.8 ms, bimodal
(about 24 ms and 43 ms: scans the filter skipped); DS3 mean 46.4 ms (22 Hz),
median 43.4 ms, 5-95 % 18.2-77.9 ms, 99 % 106 ms; both runs together mean 35.2
ms (28 Hz), 5 % 17.4 ms. DS2 also has pose gaps of 1.98 s and 1.75 s (with
stalls of the other streams) and a 27.8 s pause of the whole logger.
**Chosen: intervals uniform in [17, 53] ms** (whole milliseconds; mean 35 ms, 28.6 Hz; neither the
bimodality nor the 100 ms tail nor the gaps are modelled).

Pose noise (residual of a robust local quadratic fit over +-0.25 s, each
sample left out of its own fit; MAD standard deviations): DS2 along the heading
0.038 m (0.028 m at 1-2 m/s, 0.045 m at 3-5 m/s, 0.076 m above 5 m/s), across
0.017 m, heading 0.0079 rad; DS3 along 0.016 m, across 0.013 m, heading 0.0075
rad. **Chosen: along 0.03 m, across 0.015 m, heading 0.008 rad**, white
(lag-one autocorrelation of the residuals 0.2-0.3 in DS2, about 0 in DS3).

Jumps (a sample whose residual exceeds 0.2 m, about five along-track
deviations; neighbouring samples within 0.15 s count as one jump): DS2 10 in
4504 samples (0.22 % of the samples, one every 13 s), each above 0.2 m for
about two samples; sizes 0.20-0.39 m and one of 0.99 m (after a 2 s gap); mean
excess over 0.2 m 0.13 m; the heading does not jump (its residual at the
jumps 0.003-0.016 rad). DS3 none (largest residual 0.18 m). **Chosen: 0.2 %
of the samples (one jump every 17 s), size 0.2 m plus an exponential excess
of mean 0.13 m, random direction, decaying with 0.04 s** (at the next sample,
about 25 ms later, the residual is 0.3-0.7 of its peak).

Latency: the logs hold stamps, not arrival times, so only the pose's age
relative to the IMU shows: the pose's yaw change over five samples matches the
integrated gyro best when the gyro is read 30-35 ms earlier (residual 0.0136 rad
against 0.0249 rad unshifted in DS2; 0.0142 against 0.0251 in DS3). **Chosen:
0.03 s**, a lower bound of the true age.

Speed scale (pose speed from the local fit's slope, projected on the heading,
over the odometer's ``vx``, forward above 0.3 m/s): DS2 1.037 (means), 1.025
(distances over the first 115 s), 1.01-1.04 in every band of odometer speed
from 1 to 6 m/s; DS3 0.982 and 0.976. The odometer therefore reads 0.96-0.98 of
the true speed in DS2 and 1.02 in DS3: a few per cent, its sign changing
between runs. (Ratios from consecutive raw poses, noise and jumps included,
spread much wider: the median of raw step speed over odometer speed is 1.21 in
DS2, 1.02 in DS3; resampled at 50 ms, 10-90 % 0.52-1.93.) **Chosen: a fixed
scale of 0.97** (DS2, the run at racing speeds), the same for every car and
seed: a study's results stay reproducible and comparable between cars, and a
sensitivity to the scale is studied by overriding it, not by a seed.
Noise: second differences of ``vx`` give 0.008 m/s (DS2) and 0.001 m/s (DS3).
**Chosen: 0.01 m/s.**

Gyro: the IMU's ``wz`` is in deg/s, not rad/s as the logger's notes say: the
pose's yaw change over 1 s windows equals the integrated ``wz * pi / 180``
times 0.994 (DS2) and 1.002 (DS3), read 30 ms earlier. Bias from the same
fit -0.0069 and -0.0061 rad/s; at standstill (332 and 159 samples) -0.0059 and
-0.0071 rad/s. Noise at standstill 0.027 and 0.024 rad/s; from second
differences while driving 0.026 and 0.027 rad/s. **Chosen: bias -0.0065 rad/s,
noise 0.026 rad/s**, no scale error.

The script that measured these lives outside the repository; the figures are
reproducible from the shared CSV files with numpy alone.
"""

from __future__ import annotations

from collections.abc import Callable

from rkmpc.core.registry import Registry
from rkmpc.vehicle.sensors.components import Localiser, WheelSpeedSensor, YawRateSensor
from rkmpc.vehicle.sensors.profile import SensorProfile

__all__ = ["SENSOR_PROFILES", "f1tenth_real", "get_sensor_profile", "sensor_profile_names"]


def f1tenth_real() -> SensorProfile:
    """The real F1TENTH car's sensors (module docstring: the measured basis of every number)."""
    return SensorProfile(
        name="f1tenth-real",
        summary="particle-filter pose (28 Hz, 30 ms late, noise, jumps), VESC speed x0.97, biased gyro; "
        "no wheel angle, no side-slip",
        localiser=Localiser(
            along_track_std=0.03,
            cross_track_std=0.015,
            heading_std=0.008,
            jump_probability=0.002,
            jump_min=0.2,
            jump_mean_excess=0.13,
            jump_recovery=0.04,
            min_interval=0.017,
            max_interval=0.053,
            latency=0.03,
        ),
        wheel_speed=WheelSpeedSensor(scale=0.97, noise_std=0.01),
        yaw_rate=YawRateSensor(bias=-0.0065, noise_std=0.026),
        measures_steer_angle=False,
        measures_slip_angle=False,
    )


#: Sensor profiles by name.
SENSOR_PROFILES: Registry[Callable[[], SensorProfile]] = Registry(
    "sensor profile",
    {
        "ideal": lambda: SensorProfile(name="ideal", summary="every field true and current"),
        "no-steer": lambda: SensorProfile(
            name="no-steer",
            summary="true pose, speed and yaw rate; no wheel angle, no side-slip (the F1TENTH gym's)",
            measures_steer_angle=False,
            measures_slip_angle=False,
        ),
        "f1tenth-real": f1tenth_real,
    },
)


def sensor_profile_names() -> list[str]:
    """The named profiles, in the order of :data:`SENSOR_PROFILES`."""
    return list(SENSOR_PROFILES)


def get_sensor_profile(name: str) -> SensorProfile:
    """The profile ``name``; :class:`~rkmpc.core.registry.UnknownNameError` naming the known ones."""
    return SENSOR_PROFILES[name]()
