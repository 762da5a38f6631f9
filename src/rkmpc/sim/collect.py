"""Collect training transitions by driving a controller in a scenario."""

from __future__ import annotations

from dataclasses import asdict, replace
from typing import Any

from rkmpc.core.versions import versions
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.excitation import ExcitationConfig, random_excitation
from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.wrappers import NoiseStd


def collect(
    scenario: Scenario,
    *,
    controller: str = "lmpc",
    laps: int = 2,
    seed: int = 0,
    noise: NoiseStd | None = None,
    model: object = None,
) -> TransitionDataset:
    """Drive ``controller`` for ``laps`` laps and return the logged transitions.

    The run is :func:`rkmpc.sim.run.drive` with
    ``RunSpec(controller, laps=laps, seed=seed, noise=noise)``; its step log
    becomes one episode (:meth:`TransitionDataset.from_log`). Observations are
    what the controller saw (noisy when ``noise`` is given); commands are the
    set-points it sent. A run that ends early (off track, timeout) still
    returns its data; the outcome is in the metadata. :func:`record` returns
    the run as well.

    Parameters
    ----------
    scenario : Scenario
        Track, car and reference.
    controller : str
        Controller registry name (``"lmpc"``, ``"pp"``, ...).
    laps : int
        Laps to drive (>= 1).
    seed : int
        Seed of the run (measurement noise).
    noise : NoiseStd or None
        Measurement noise, or None for exact observations.
    model : optional
        The model of a learned controller.

    Returns
    -------
    TransitionDataset
        With metadata ``vehicle``, ``track``, ``scale``, ``dt`` (s),
        ``wheelbase`` (m), ``seed``, ``controller``, ``laps``, ``noise``,
        ``sensors`` (the sensor profile's name), ``sensors_ideal``, ``pose_latency`` (s, the
        localiser's latency), ``outcome``,
        ``completed``, ``progress_laps``, ``lap_times``, ``fallback_count``,
        ``steps``, ``status_counts``, ``rkmpc_version``, ``versions``,
        ``source = "collect"`` and the contract
        (:attr:`TransitionDataset.contract`: car, period, scale, state ranges).
    """
    _, data = record(
        scenario,
        RunSpec(controller, laps=laps, seed=seed, noise=noise),
        model=model,
    )
    return data


def record(scenario: Scenario, spec: RunSpec, *, model: object = None) -> tuple[SimResult, TransitionDataset]:
    """Drive ``spec`` (:func:`rkmpc.sim.run.drive`): the run and its transitions (see :func:`collect`)."""
    result = drive(scenario, spec, model=model)
    all_versions = versions()
    metadata: dict[str, Any] = {
        "source": "collect",
        "vehicle": scenario.vehicle_name,
        "car": scenario.car.plant.car,
        "track": scenario.track.name,
        "scale": scenario.track.scale,
        "dt": scenario.dt,
        "wheelbase": scenario.vehicle.wheelbase,
        "seed": spec.seed,
        "controller": spec.controller,
        "laps": spec.laps,
        "noise": None if spec.noise is None else asdict(spec.noise),
        "sensors": scenario.car.sensors.name,
        "sensors_ideal": scenario.car.sensors.is_ideal,
        "pose_latency": scenario.car.sensors.pose_latency,
        "outcome": result.outcome,
        "completed": result.completed,
        "progress_laps": result.progress,
        "lap_times": [float(t) for t in result.lap_times],
        "fallback_count": result.fallback_count,
        "steps": len(result.log),
        "status_counts": dict(sorted(result.status_counts.items())),
        "rkmpc_version": all_versions["rkmpc"],
        "versions": all_versions,
    }
    # The log records the scenario's contract (drive); the data set adds its state ranges.
    return result, TransitionDataset.from_log(result.log, metadata=metadata, dt=scenario.dt)


def excitation_lateral_accel(scenario: Scenario) -> float:
    """Largest lateral acceleration (m/s^2) the random excitation asks of the scenario's car.

    Twice the speed profile's lateral limit (the excitation explores beyond what the track asks),
    at most the road's grip ``mu g``: 8 m/s^2 for the 1:10 car, 9.81 m/s^2 for the full-size car.
    """
    return min(2.0 * scenario.limits.lateral_accel, scenario.vehicle.mu * scenario.vehicle.gravity)


def collect_excitation(scenario: Scenario, *, n_samples: int = 50_000, seed: int = 0) -> TransitionDataset:
    """Random-excitation transitions of the scenario's car in open space (for KMPC).

    Speeds are drawn within the scenario's speed limits, wheel angles within
    90 % of the steering limit and the lateral acceleration they ask for within
    :func:`excitation_lateral_accel`; see :mod:`rkmpc.learning.data.excitation`.

    Parameters
    ----------
    scenario : Scenario
        Supplies the car, its plant and its speed limits (the track is unused).
    n_samples : int
        Transitions to record.
    seed : int
        Seed of every random choice.
    """
    config = ExcitationConfig(
        n_samples=n_samples,
        speed_range=(scenario.limits.min_speed, scenario.limits.max_speed),
        max_lateral_accel=excitation_lateral_accel(scenario),
        seed=seed,
    )
    plant = scenario.make_plant(seed)
    obs, command, next_obs, episode = random_excitation(plant, config, dt=scenario.dt)
    all_versions = versions()
    metadata: dict[str, Any] = {
        "source": "excitation",
        "vehicle": scenario.vehicle_name,
        "car": scenario.car.plant.car,
        "dt": scenario.dt,
        "wheelbase": scenario.vehicle.wheelbase,
        "seed": seed,
        "excitation": asdict(config),
        "rkmpc_version": all_versions["rkmpc"],
        "versions": all_versions,
    }
    data = TransitionDataset(
        obs=obs, command=command, next_obs=next_obs, dt=scenario.dt, episode=episode, metadata=metadata
    )
    # The car in open space: the data do not depend on a track, so no scale is recorded.
    return data.with_contract(replace(scenario.provenance(), scale=None))
