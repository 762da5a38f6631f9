"""The closed loop: plant -> observation -> controller -> command -> plant."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rkmpc.control.base import STATUS_CODES, Controller
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError, PlantIntegrationError
from rkmpc.core.observation import OBSERVATION_FIELDS, Command, Observation
from rkmpc.sim.laps import LapCounter
from rkmpc.sim.log import StepLog
from rkmpc.track.reference import Reference
from rkmpc.track.track import Track
from rkmpc.vehicle.plants.base import Plant

#: Ways a run can end (``"plant_failure"``: the plant could not integrate a step, see
#: :class:`rkmpc.core.errors.PlantIntegrationError`; ``"stopped"``: the controller stopped the car,
#: which then stood still, for :data:`STOPPED_S`; why is in :attr:`SimResult.failure`).
OUTCOMES = ("completed", "off_track", "timeout", "diverged", "plant_failure", "stopped")
#: How long (s) a car must stand still, its controller refusing to drive it (a stop command with
#: a status other than ``ok``: a spun car whose heading is no longer admissible, an observation
#: refused), for the run to end as ``"stopped"`` instead of waiting for the time limit.
STOPPED_S = 2.0
#: Speed (m/s) below which a car stands still.
STILL_SPEED = 0.05
#: Most steps a run may take: 2 million, over 27 hours of driving at 20 Hz. A longer time limit
#: (a track in the wrong unit, a huge ``--scale``) is refused before the run rather than left to
#: run for days with no output.
MAX_STEPS = 2_000_000


@dataclass(frozen=True)
class SimConfig:
    """Settings of a closed-loop run.

    Parameters
    ----------
    dt : float
        Control period (s); the paper uses 50 ms.
    laps : int
        Laps to drive.
    start_s : float
        Arc length on the reference path where the car starts (m).
    flying_start : bool
        Start at the reference speed and feed-forward wheel angle (True), or
        from standstill with straight wheels (False).
    max_time : float or None
        Time limit (s); None means three times the profile's lap time per lap
        plus 10 s. Reaching it ends the run as ``"timeout"`` (the car drove on, or crawled, but
        did not finish). A limit above :data:`MAX_STEPS` periods is refused by :func:`simulate`.
    """

    dt: float = 0.05
    laps: int = 1
    start_s: float = 0.0
    flying_start: bool = True
    max_time: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ParameterError(f"SimConfig.dt must be > 0, got {self.dt}")
        if self.laps < 1:
            raise ParameterError(f"SimConfig.laps must be >= 1, got {self.laps}")
        if self.max_time is not None and not (math.isfinite(self.max_time) and self.max_time > 0):
            raise ParameterError(f"SimConfig.max_time must be finite and > 0, got {self.max_time}")


@dataclass
class SimResult:
    """Outcome and log of one run.

    Parameters
    ----------
    log : StepLog
        One row per control step.
    outcome : str
        One of :data:`OUTCOMES`.
    progress : float
        Distance driven along the reference path, in laps.
    lap_times : list of float
        Time of each completed lap (s).
    fallback_count : int
        Steps on which the controller fell back.
    status_counts : dict of str to int
        The controller's steps by status (:data:`rkmpc.control.base.STATUSES`).
    lap_length : float
        Length of one lap of the reference path (m).
    diagnostics : dict of str to float
        The controller's own counts at the end (:meth:`rkmpc.control.base.Controller.diagnostics`).
    failure : str or None
        Why the run ended early: the plant's error when ``outcome`` is ``"plant_failure"``, the
        controller's last refusal when it is ``"stopped"``; else None.
    """

    log: StepLog
    outcome: str
    progress: float
    lap_length: float
    lap_times: list[float] = field(default_factory=list)
    fallback_count: int = 0
    status_counts: dict[str, int] = field(default_factory=dict)
    diagnostics: dict[str, float] = field(default_factory=dict)
    failure: str | None = None

    @property
    def completed(self) -> bool:
        """Whether all requested laps were driven."""
        return self.outcome == "completed"


def log_columns(state_names: tuple[str, ...]) -> list[str]:
    """Column names of the step log for a plant with these state names."""
    return [
        "t",
        "s",
        "progress",
        *OBSERVATION_FIELDS,
        *(f"state_{name}" for name in state_names),
        "cmd_speed",
        "cmd_steer",
        "wheel_angle",
        "x_r",
        "y_r",
        "theta_r",
        "v_r",
        "delta_r",
        "lateral_error",
        "heading_error",
        "track_margin",
        "solve_time_s",
        "status",
    ]


def simulate(
    plant: Plant,
    controller: Controller,
    track: Track,
    reference: Reference,
    config: SimConfig | None = None,
    *,
    on_step: Callable[[float, float], None] | None = None,
) -> SimResult:
    """Drive ``plant`` with ``controller`` around ``track`` and log every step.

    The run ends when the requested laps are driven, when the car's centre of
    gravity leaves the track (``"off_track"``, never an exception), when the
    state turns non-finite (``"diverged"``), when the plant cannot integrate a
    step (``"plant_failure"``: a :class:`~rkmpc.core.errors.PlantIntegrationError`
    is caught, its message kept in :attr:`SimResult.failure` and the log's
    metadata), when the controller has stopped the car and it stood still for
    :data:`STOPPED_S` (``"stopped"``: the controller refuses to drive it on, its
    status and message kept as the failure) or at the time limit.

    Parameters
    ----------
    plant : Plant
        The simulated car; it is reset to the start pose.
    controller : Controller
        Any controller; it is reset first.
    track : Track
        Track boundaries, for the off-track check.
    reference : Reference
        Path and speed profile; errors are measured against its path.
    config : SimConfig, optional
        Control period, laps, start and time limit.
    on_step : callable, optional
        Called as ``on_step(time, progress_in_laps)`` after every step (for
        progress bars).

    Returns
    -------
    SimResult
    """
    cfg = config if config is not None else SimConfig()
    length = reference.path.length
    s0 = _start(plant, reference, cfg)
    controller.reset()
    lap_time = reference.profile.lap_time
    max_time = cfg.max_time if cfg.max_time is not None else 3.0 * cfg.laps * lap_time + 10.0
    max_steps = math.ceil(max_time / cfg.dt) + 1
    if not max_steps <= MAX_STEPS:
        raise ParameterError(
            f"simulate: the time limit of {max_time:.4g} s would allow {max_steps:.4g} steps of "
            f"{cfg.dt:g} s, more than {MAX_STEPS:.0e}: is the track ({length:.4g} m) too long, "
            "or the time limit?"
        )
    log = StepLog(log_columns(plant.STATE_NAMES), capacity=min(max_steps, 20000))
    names = plant.STATE_NAMES
    pose_index = (names.index("x"), names.index("y"), names.index("yaw"))
    speed_index = names.index("v") if "v" in names else None
    standing = 0  # steps the car stood still, stopped by its controller
    laps = LapCounter(reference.path, s0)
    s_track: float | None = None
    outcome = "timeout"
    failure: str | None = None
    for _ in range(max_steps):
        obs = plant.observe()
        t = plant.time
        state = plant.state
        if not np.all(np.isfinite(state)):
            outcome = "diverged"
            break
        # Errors of the true pose against the reference path; progress unwrapped across the line.
        true_x, true_y, true_yaw = (float(state[i]) for i in pose_index)
        proj, _ = laps.update(true_x, true_y, t, cfg.dt, first=len(log) == 0)
        s_track, _, margin = track.boundary_offsets(true_x, true_y, s_track)
        if laps.distance >= cfg.laps * length:
            outcome = "completed"
            break
        on_track = margin >= 0.0
        command = controller.step(obs) if on_track else None
        errors = (proj.lateral, wrap_scalar(true_yaw - float(proj.heading)), margin)
        log.append(
            _log_row(t, proj.s, laps.distance, obs, state, plant, controller, command, reference, errors)
        )
        if command is None:
            outcome = "off_track"
            break
        speed = abs(float(state[speed_index] if speed_index is not None else obs.speed))
        refused = command.speed == 0.0 and controller.info.status != "ok" and speed < STILL_SPEED
        standing = standing + 1 if refused else 0
        if standing * cfg.dt >= STOPPED_S:
            outcome = "stopped"
            failure = (
                f"the controller stopped the car, which stood still for {STOPPED_S:g} s until {t:.2f} s; "
                f"its last step: {controller.info.status}, {controller.info.message}"
            )
            break
        try:
            plant.step(command, cfg.dt)
        except PlantIntegrationError as exc:
            outcome, failure = "plant_failure", str(exc)
            break
        if on_step is not None:
            on_step(t, laps.distance / length)
    lap_times = list(np.diff([0.0, *laps.crossings]).astype(float)) if laps.crossings else []
    log.metadata["outcome"] = outcome
    log.metadata["lap_times"] = lap_times
    diagnostics = controller.diagnostics()
    log.metadata["diagnostics"] = diagnostics
    log.metadata["status_counts"] = dict(controller.status_counts)
    log.metadata["failure"] = failure
    return SimResult(
        log=log,
        outcome=outcome,
        progress=laps.distance / length,
        lap_length=length,
        lap_times=lap_times,
        fallback_count=controller.fallback_count,
        status_counts=dict(controller.status_counts),
        diagnostics=diagnostics,
        failure=failure,
    )


def _start(plant: Plant, reference: Reference, cfg: SimConfig) -> float:
    """Reset the plant at the start of the run; returns the start's arc length (m)."""
    path = reference.path
    s0 = cfg.start_s % path.length
    start = path.position(s0)
    yaw0 = float(path.heading(s0))
    if cfg.flying_start:
        speed0 = float(reference.profile.speed(s0))
        steer0 = math.atan(reference.wheelbase * float(path.curvature(s0)))
    else:
        speed0, steer0 = 0.0, 0.0
    plant.reset(float(start[0]), float(start[1]), yaw0, speed0, steer0)
    return s0


def _log_row(
    t: float,
    s: float,
    progress: float,
    obs: Observation,
    state: np.ndarray,
    plant: Plant,
    controller: Controller,
    command: Command | None,
    reference: Reference,
    errors: tuple[float, float, float],
) -> np.ndarray:
    """One row of the step log (see :func:`log_columns`); NaN command columns when there is none."""
    if command is None:
        cmd = (math.nan, math.nan, math.nan, math.nan)
    else:
        info = controller.info
        cmd = (command.speed, command.steer, info.solve_time_s, STATUS_CODES.get(info.status, math.nan))
    return np.concatenate(
        [
            (t, s, progress),
            obs.as_array(),
            state,
            cmd[:2],
            (plant.wheel_angle,),
            _reference_row(reference, s),
            errors,
            cmd[2:],
        ]
    )


def _reference_row(reference: Reference, s: float) -> tuple[float, float, float, float, float]:
    """``(x_r, y_r, theta_r, v_r, delta_r)`` of the reference at arc length ``s``."""
    path = reference.path
    pos = path.position(s)
    return (
        float(pos[0]),
        float(pos[1]),
        float(path.heading(s)),
        float(reference.profile.speed(s)),
        math.atan(reference.wheelbase * float(path.curvature(s))),
    )
