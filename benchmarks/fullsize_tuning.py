"""Held-out tracks on which the full-size car's ``rkmpc`` settings were chosen (issue 11).

The full-size residual settings (:func:`rkmpc.config.scaling.speed_priced` of the 1:10 car's carried
over, written out in ``rkmpc/config/presets/fullsize.toml``) are tuned here, never on the shared
tracks. The held-out set, written to a folder as TUM centre-line files:

- ``builtin-x30`` and ``oval-x30``: the built-in and oval tracks written out 10 times larger,
  points 1 m apart, and loaded at scale 3 (2.6 km and 1.7 km). A result moves by a few points
  with how a file is written and scaled. The preset gives on the oval: -31 % on the file it was
  tuned on, -33 % on this one (the same points to 0.5 mm), -27 % with these points written out
  at 30x and loaded at scale 1, -24 % at 30x with points 1.5 m apart. That is the noise floor
  of any comparison here (the cause of the scale's effect is not found);
- ``fast0`` ... ``fast3``: seeded random polygons of 6-9 corners on a 700-1600 m wide circle,
  each corner rounded with a radius of 15, 25, 40, 70 or 120 m, so that 25 m/s straights end in
  hairpins (3.0-4.0 km). These show the weave a too-cheap steering correction starts at 25 m/s.
- ``kink0`` and ``kink1`` (its mirror image): a long straight into an 11 m hairpin and, 70 m on,
  a 19 m kink the other way (3.3 km), the sequence where position weight 16 left Sakhir. Weight
  16 completes both (-62 % and -61 %, preset -57 %), so they do not reproduce that failure.

For each track the script learns the ``rkmpc`` model from two LMPC laps, drives the LMPC, then
``rkmpc`` with the preset's settings and with each named variant, and prints the lateral,
lateral-maximum and heading changes against the LMPC (or where the car left the track)::

    python benchmarks/fullsize_tuning.py OUT_DIR 'p8=position_weight:8;p16=position_weight:16' [TRACKS]

with ``TRACKS`` a comma-separated subset of the names above (default: all eight). A variant's
``position_weight``, ``top_price`` and ``floor`` are the keyword arguments of ``speed_priced``
(the preset's: 8, 4 and 2), which recomputes the settings from the carried-over ones; any other
key replaces that field of the ``RKMPCConfig`` it gives. The figures of
issue 11's sixth note came from an earlier copy of this script, run with the variants
``'flat=lateral_accel_weight:0,steer_weight:17;p8=position_weight:8'`` on the first six and
``'p16=position_weight:16;p32=position_weight:32'`` on ``fast3,fast2,builtin-x30,oval-x30``:
a higher position weight at the preset's steering price gained on each track it drove,
until 32 left ``fast2``; on the shared tracks 16 left Sakhir, so the preset stayed at 4. In the
seventh session 8 (``'p8=position_weight:8'``, 2-7 points better on the seven tracks it drove)
completed all shared tracks and became the preset; ``docs/cars.md`` has the other variants tried.
Then the slip drift (``RKMPCConfig.slip_drift``) joined the preset: ``'nodrift=slip_drift:false'``
drives without it (``true``/``false`` set a switch).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from scenarios import with_controllers

from rkmpc.config.loader import load_preset
from rkmpc.config.scaling import carry_over, speed_priced
from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.core.io import atomic_write
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.track.builtin import builtin_track

KEYS = ("lateral_error_mean_m", "lateral_error_max_m", "heading_error_mean_rad")
#: The keyword arguments of :func:`rkmpc.config.scaling.speed_priced` that made the preset's settings.
PRESET_PRICING = {"position_weight": 8.0, "top_price": 4.0, "floor": 2.0}
RADII_M = (15.0, 25.0, 40.0, 70.0, 120.0)


def _write(path: Path, xy: np.ndarray, right: np.ndarray, left: np.ndarray) -> Path:
    """Write a TUM centre-line file (under a temporary name, renamed when complete)."""
    rows = np.column_stack([xy, right, left])
    with atomic_write(path) as handle:
        np.savetxt(handle, rows, fmt="%.3f", delimiter=",", header="x_m,y_m,w_tr_right_m,w_tr_left_m")
    return path


def _resample(xy: np.ndarray, step: float) -> np.ndarray:
    closed = np.vstack([xy, xy[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    grid = np.arange(0.0, s[-1], step)
    return np.column_stack([np.interp(grid, s, closed[:, 0]), np.interp(grid, s, closed[:, 1])])


def _rounded_polygon(corners: np.ndarray, radii: np.ndarray, step: float = 2.0) -> np.ndarray:
    """Points of a closed polygon whose corners are circular arcs of the given radii (m)."""
    points = []
    before, after = np.roll(corners, 1, axis=0), np.roll(corners, -1, axis=0)
    for i, (a, b, c) in enumerate(zip(before, corners, after, strict=True)):
        d1 = (b - a) / np.linalg.norm(b - a)
        d2 = (c - b) / np.linalg.norm(c - b)
        turn = np.arccos(np.clip(d1 @ d2, -1.0, 1.0))
        side = np.sign(d1[0] * d2[1] - d1[1] * d2[0])
        start = b - d1 * radii[i] * np.tan(turn / 2)
        centre = start + side * radii[i] * np.array([-d1[1], d1[0]])
        a0 = np.arctan2(*(start - centre)[::-1])
        count = max(2, int(radii[i] * turn / step))
        for k in range(count):
            angle = a0 + side * turn * k / count
            points.append(centre + radii[i] * np.array([np.cos(angle), np.sin(angle)]))
    return _resample(np.array(points), step)


def _fast_circuit(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    while True:
        n = int(rng.integers(6, 10))
        angles = np.sort(rng.uniform(0.0, 2 * np.pi, n))
        if np.min(np.diff(np.append(angles, angles[0] + 2 * np.pi))) < 0.35:
            continue
        radius = rng.uniform(350.0, 800.0, n) * np.where(rng.uniform(size=n) < 0.2, 0.55, 1.0)
        corners = np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])
        radii = rng.choice(RADII_M, n)
        legs = np.roll(corners, -1, axis=0) - corners
        d = legs / np.linalg.norm(legs, axis=1, keepdims=True)
        turn = np.arccos(np.clip(np.sum(np.roll(d, 1, axis=0) * d, axis=1), -1.0, 1.0))
        tangent = radii * np.tan(turn / 2)
        if np.all(tangent + np.roll(tangent, -1) <= 0.8 * np.linalg.norm(legs, axis=1)):
            return _rounded_polygon(corners, radii)


def _kink_circuit(mirror: bool) -> np.ndarray:
    """A long straight into an 11 m hairpin, 70 m on into a 19 m kink the other way, then back."""
    corners = np.array([(-800.0, 0.0), (0.0, 0.0), (-23.9, 65.8), (326.0, 672.0), (-700.0, 750.0)])
    radii = np.array([25.0, 11.0, 19.0, 40.0, 70.0])
    xy = _rounded_polygon(corners, radii)
    return xy * np.array([1.0, -1.0]) if mirror else xy


def held_out_tracks(folder: Path) -> dict[str, tuple[Path, float]]:
    """Write the held-out tracks into ``folder``; their names, files and the scale to load them at."""
    folder.mkdir(parents=True, exist_ok=True)
    tracks = {}
    for name in ("builtin", "oval"):
        track = builtin_track(name)
        s = np.arange(0.0, track.length, 0.1)  # 1 m apart at 10x, as tuned
        xy = track.centerline.position(s) * 10.0
        right, left = track.width_right(s) * 10.0, track.width_left(s) * 10.0
        tracks[f"{name}-x30"] = (_write(folder / f"{name}-x10.csv", xy, right, left), 3.0)
    for k in range(4):
        xy = _fast_circuit(200 + k)
        width = np.full(len(xy), 6.0)
        tracks[f"fast{k}"] = (_write(folder / f"fast{k}.csv", xy, width, width), 1.0)
    for k, mirror in enumerate((False, True)):
        xy = _kink_circuit(mirror)
        width = np.full(len(xy), 6.0)
        tracks[f"kink{k}"] = (_write(folder / f"kink{k}.csv", xy, width, width), 1.0)
    return tracks


def _value(text: str) -> float | bool:
    """A field's value: ``true`` or ``false`` for a switch, otherwise a number."""
    return text == "true" if text in ("true", "false") else float(text)


def _parse(spec: str) -> dict[str, dict[str, float | bool]]:
    variants = {}
    for part in filter(None, spec.split(";")):
        name, _, pairs = part.partition("=")
        variants[name] = {k: _value(v) for k, v in (p.split(":") for p in pairs.split(",") if p)}
    return variants


def variant_settings(scenario: Scenario, fields: dict[str, float | bool]) -> RKMPCConfig:
    """rkmpc's settings of a variant: the 1:10 car's carried over to the scenario's car and priced
    by :func:`speed_priced` with the preset's arguments, those of ``fields`` replaced; then the
    other ``fields`` replace those fields of the result."""
    small, car = load_preset("f1tenth"), scenario.car
    scaled = carry_over(small.controllers.rkmpc, small.vehicle, small.limits, car.vehicle, car.limits)
    pricing = {**PRESET_PRICING, **{k: float(v) for k, v in fields.items() if k in PRESET_PRICING}}
    rest = {k: v for k, v in fields.items() if k not in PRESET_PRICING}
    priced = speed_priced(
        scaled,
        car.vehicle,
        car.limits,
        position_weight=pricing["position_weight"],
        top_price=pricing["top_price"],
        floor=pricing["floor"],
    )
    return replace(priced, **rest)


def main(folder: Path, spec: str, names: list[str] | None = None) -> None:
    print("| track | setting | rkmpc vs LMPC: lat / lat max / head |")
    print("|---|---|---|")
    for track, (file, scale) in held_out_tracks(folder).items():
        if names is not None and track not in names:
            continue
        scenario = load_scenario(file, vehicle="fullsize", scale=scale)
        models, _ = learn_models(scenario, ModelPlan(controllers=("rkmpc",)))
        _, lmpc = run_controller(scenario, RunSpec("lmpc"))
        for name, fields in {"preset": {}, **_parse(spec)}.items():
            # The preset drives with the file's numbers; a variant with speed_priced's (the same to 1e-12).
            settings = scenario.car.controllers.rkmpc if not fields else variant_settings(scenario, fields)
            _, m = run_controller(
                with_controllers(scenario, rkmpc=settings), RunSpec("rkmpc"), model=models["rkmpc"]
            )
            if not (m.completed and lmpc.completed):
                print(f"| {track} | {name} | left at {m.progress:.0%} |", flush=True)
                continue
            changes = " / ".join(f"{100 * (m[k] - lmpc[k]) / lmpc[k]:+.1f}%" for k in KEYS)
            print(f"| {track} | {name} | {changes} |", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="where the held-out tracks are written")
    parser.add_argument(
        "variants", nargs="?", default="", help="'NAME=FIELD:VALUE,...;...' (see the module's notes)"
    )
    parser.add_argument("tracks", nargs="?", default=None, help="comma-separated held-out track names")
    args = parser.parse_args()
    main(args.folder, args.variants, None if args.tracks is None else args.tracks.split(","))
