"""Laps read for tyre identification: the runs to predict, their held-out time, the signals' spread.

:func:`prepare` turns transitions into the :class:`~rkmpc.learning.tyre_dynamics.Runs` that
:mod:`rkmpc.learning.tyre_fit` predicts: with a measured side slip, every usable transition is a
run of one period from its measured start; without it, runs of :data:`RUN_PERIODS` consecutive
transitions of one episode start from the steady-state side slip of the candidate's rear tyres
(:func:`steady_start`) and are scored after :data:`BURN_IN` periods. The wheel angle is the
measured one, or the one the identified servo runs from the commands
(:func:`~rkmpc.learning.identification.wheel_from_commands`). A transition is usable when every
signal it needs is finite at both ends and the car is faster than the minimum speed there.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import MIN_TRANSITIONS, IdentifiedModel, wheel_from_commands
from rkmpc.learning.model_choice import MIN_LATERAL_ACCELERATION
from rkmpc.learning.tyre_dynamics import Chassis, Runs, slip_angles
from rkmpc.learning.tyre_model import AxleCurve, nominal_curves
from rkmpc.vehicle.params import VehicleParams

__all__ = [
    "BURN_IN",
    "MIN_SLIP_REACH",
    "RUN_PERIODS",
    "TyreData",
    "chains",
    "confounded",
    "limits",
    "prepare",
    "reach_notes",
    "steady_start",
    "unexcited",
]

_SPEED, _YAW_RATE, _SLIP, _STEER = (
    OBSERVATION_FIELDS.index(n) for n in ("speed", "yaw_rate", "slip_angle", "steer_angle")
)
#: Periods of a run predicted from a steady-state start when the side slip is not measured ...
RUN_PERIODS = 8
#: ... and the first periods of it not scored (the lateral modes forget the start within them).
BURN_IN = 3
#: A slip angle (rad, 98th percentile) below which the data do not load the tyres.
MIN_SLIP_REACH = 0.01


@dataclass(frozen=True)
class TyreData:
    """The runs to predict and what identification reports of the data.

    Parameters
    ----------
    runs : Runs
        Every run (M of them).
    cover : list of numpy.ndarray
        The transitions each run spans (indices into the data set).
    time : numpy.ndarray
        Per run, the transition whose held-out block it is scored in (its first scored one), (M,).
    usable : numpy.ndarray
        The transitions some run spans, (N,) bool.
    scales : tuple of float
        Standard deviation of the one-step change of the yaw rate (rad/s) and of the lateral
        velocity (m/s; 1e-6 when the side slip is not measured): each error is divided by it.
    slip : bool
        Whether the side slip is measured.
    wheel : str
        ``measured`` or ``commands``.
    reach : tuple of float
        98th percentile of the front and rear slip angles (rad) over the usable transitions.
    lateral_accel : float
        RMS lateral acceleration ``v r`` (m/s^2) of the usable transitions.
    """

    runs: Runs
    cover: list[np.ndarray]
    time: np.ndarray
    usable: np.ndarray
    scales: tuple[float, float]
    slip: bool
    wheel: str
    reach: tuple[float, float]
    lateral_accel: float


def prepare(
    data: TransitionDataset, vehicle: VehicleParams, servo: IdentifiedModel, min_speed: float
) -> TyreData:
    """The runs of ``data`` for ``vehicle``'s chassis; ``servo`` runs the wheel when it is not measured."""
    obs, nxt = np.asarray(data.obs, dtype=float), np.asarray(data.next_obs, dtype=float)
    episode = np.asarray(data.episode)
    slip = int((np.isfinite(obs[:, _SLIP]) & np.isfinite(nxt[:, _SLIP])).sum()) >= MIN_TRANSITIONS
    measured = int((np.isfinite(obs[:, _STEER]) & np.isfinite(nxt[:, _STEER])).sum()) >= MIN_TRANSITIONS
    if measured:
        wheel0, wheel1 = obs[:, _STEER], nxt[:, _STEER]
    else:
        wheel1 = wheel_from_commands(servo, data, vehicle)
        starts = np.r_[True, episode[1:] != episode[:-1]]
        first = np.where(np.isfinite(obs[:, _STEER]), obs[:, _STEER], np.asarray(data.command)[:, 1])
        wheel0 = np.where(starts, first, np.roll(wheel1, 1))
    beta0 = obs[:, _SLIP] if slip else np.zeros(len(obs))
    beta1 = nxt[:, _SLIP] if slip else np.zeros(len(obs))
    v0, v1 = obs[:, _SPEED] / np.cos(beta0), nxt[:, _SPEED] / np.cos(beta1)
    r0, r1 = obs[:, _YAW_RATE], nxt[:, _YAW_RATE]
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(v0 + v1 + r0 + r1 + wheel0 + wheel1 + beta0 + beta1)
        usable &= (v0 > min_speed) & (v1 > min_speed)
    chassis = Chassis.of(vehicle)
    if not slip:  # the steady-state side slip of the nominal rear tyres (see _start), for the reach
        v, r = np.where(usable, v0, 1.0), np.where(usable, r0, 0.0)
        beta0 = np.arctan(
            chassis.lr * r / v - v * r / (chassis.gravity * nominal_curves(vehicle)[1].stiffness)
        )
    alpha = slip_angles(
        chassis,
        np.where(usable, v0, 1.0),
        np.where(usable, beta0, 0.0),
        np.where(usable, r0, 0.0),
        np.where(usable, wheel0, 0.0),
    )
    reach = tuple(float(np.percentile(np.abs(a[usable]), 98)) if usable.any() else 0.0 for a in alpha)
    lateral0, lateral1 = v0 * np.sin(beta0), v1 * np.sin(beta1)
    scales = (
        max(float(np.std((r1 - r0)[usable])) if usable.any() else 0.0, 1e-6),
        max(float(np.std((lateral1 - lateral0)[usable])) if slip and usable.any() else 0.0, 1e-6),
    )
    lateral_accel = float(np.sqrt(np.mean((v1 * r1)[usable] ** 2))) if usable.any() else 0.0
    if slip:
        rows = np.flatnonzero(usable)
        cover = [rows[i : i + 1] for i in range(len(rows))]
        time = rows
    else:
        cover = chains(usable, episode)
        time = np.array([c[BURN_IN] for c in cover], dtype=int)
    rows = np.array([c[0] for c in cover], dtype=int)
    spans = np.array(cover, dtype=int).reshape(len(cover), -1)

    def boundaries(start: np.ndarray, end: np.ndarray) -> np.ndarray:
        return np.column_stack([start[spans], end[spans[:, -1]]]) if len(cover) else np.zeros((0, 2))

    width = spans.shape[1] + 1 if len(cover) else 2
    scored = np.zeros((len(cover), width), dtype=bool)
    scored[:, (1 if slip else BURN_IN + 1) :] = True
    runs = Runs(
        speed=boundaries(v0, v1),
        wheel=boundaries(wheel0, wheel1),
        beta0=beta0[rows],  # replaced by the candidate's steady state without side slip (_start)
        yaw_rate0=r0[rows],
        yaw_rate=boundaries(r0, r1),
        lateral=boundaries(lateral0, lateral1) if slip else np.full((len(cover), width), np.nan),
        scored=scored,
        dt=float(data.dt),
    )
    mask = np.zeros(len(obs), dtype=bool)
    for c in cover:
        mask[c] = True
    wheel = "measured" if measured else "commands"
    return TyreData(runs, cover, time, mask, scales, slip, wheel, (reach[0], reach[1]), lateral_accel)


def chains(usable: np.ndarray, episode: np.ndarray) -> list[np.ndarray]:
    """Runs of :data:`RUN_PERIODS` consecutive usable transitions of one episode, each new one
    starting where the previous one's scored part did not reach (every transition scored once)."""
    out: list[np.ndarray] = []
    n, k = len(usable), 0
    stride = RUN_PERIODS - BURN_IN
    while k + RUN_PERIODS <= n:
        span = np.arange(k, k + RUN_PERIODS)
        if usable[span].all() and (episode[span] == episode[k]).all():
            out.append(span)
            k += stride
        else:
            k += 1
    return out


def steady_start(d: TyreData, runs: Runs, rear: AxleCurve, chassis: Chassis) -> Runs:
    """``runs`` starting from the steady-state side slip of ``rear`` when the side slip is not measured.

    In steady cornering the rear axle carries ``m v r lf / L``, so its slip angle is about
    ``v r / (g c_r)`` and the side slip ``lr r / v - v r / (g c_r)`` (``c_r`` its stiffness).
    """
    if d.slip:
        return runs
    v, r = runs.speed[:, 0], runs.yaw_rate0
    beta0 = np.arctan(chassis.lr * r / v - v * r / (chassis.gravity * rear.stiffness))
    return replace(runs, beta0=beta0)


def confounded(d: TyreData, servo: IdentifiedModel) -> bool:
    """Whether the servo run from the commands was fitted on the yaw rate's response without a side slip.

    Such a servo holds the chassis's own lag in building up yaw (:mod:`rkmpc.learning.yaw_fit`), the
    lag the stiffnesses' scale sets: the yaw rate cannot tell the two apart.
    """
    return (
        not d.slip
        and d.wheel == "commands"
        and servo.fitted_on == "yaw_rate"
        and servo.servo_structure != "nominal"
    )


def limits(d: TyreData, servo: IdentifiedModel) -> list[str]:
    """What the data cannot support, in words (warnings of the identified tyres)."""
    notes = []
    if confounded(d, servo):
        notes.append(
            "tyres: the servo was fitted on the yaw rate, so it already holds the chassis's lag in "
            "building up yaw, which the stiffnesses' scale sets: through it only their ratio (the "
            "understeer) is fitted; every candidate is also fitted with the wheel run through the "
            "servo's lag without its delay and through the nominal servo, and held-out data choose"
        )
    if not d.slip:
        notes.append(
            "tyres: the side slip is not measured: only the yaw rate's response is fitted, which fixes the "
            "ratio of the stiffnesses (the understeer gradient) and shows their scale only in the yaw "
            "transient; no Pacejka curvature is fitted"
        )
    if d.wheel == "commands":
        notes.append(
            "tyres: the wheel angle is not measured: run from the commands through the "
            f"{servo.servo_structure} servo (a controller must run it the same way)"
        )
    return notes


def unexcited(d: TyreData, n: int) -> str | None:
    """Why ``d`` (``n`` usable transitions) cannot load the tyres enough for a fit, or None."""
    if n < MIN_TRANSITIONS:
        return (
            f"only {n} transitions faster than the minimum speed with every signal "
            f"(at least {MIN_TRANSITIONS})"
        )
    if d.lateral_accel < MIN_LATERAL_ACCELERATION or max(d.reach) < MIN_SLIP_REACH:
        return (
            f"the data do not excite the tyres ({d.lateral_accel:.2f} m/s^2 lateral acceleration RMS, "
            f"slip angles up to {max(d.reach):.3f} rad; at least {MIN_LATERAL_ACCELERATION:g} "
            f"and {MIN_SLIP_REACH:g})"
        )
    return None


def reach_notes(d: TyreData, front: AxleCurve, rear: AxleCurve) -> list[str]:
    """A warning per axle whose data reach less than 80 % of its fitted peak."""
    notes = []
    for axle, curve, reach in (("front", front, d.reach[0]), ("rear", rear, d.reach[1])):
        share = float(curve.force_per_load(np.array(reach))) / curve.peak
        if share < 0.8:
            notes.append(
                f"tyres: the data reach {reach:.3f} rad on the {axle} axle, "
                f"{100 * share:.0f} % of the fitted peak {curve.peak:.2f}: the peak is an extrapolation"
            )
    return notes
