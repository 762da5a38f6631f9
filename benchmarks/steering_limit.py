"""Where the path asks for more steering than the car has, and what each controller loses there.

The kinematic wheel angle of a path is ``atan(L * kappa)`` (``L`` the wheelbase, ``kappa`` the
path's curvature). Where it comes near the steering limit (``--fraction`` of it, 0.8 by default),
the car must turn in at full lock through its servo's lag, and where it passes the limit no car of
that wheelbase can follow the line at all (docs/sensors.md measures what each controller loses
there).

Two uses:

- ``python benchmarks/steering_limit.py --tracks builtin ../shared/tracks/centerlines/*.csv``: a
  table over tracks of the largest kinematic wheel angle of the path (rad) and the metres of path
  beyond the fraction and beyond the limit itself (the `f1tenth` preset's car unless ``--vehicle``;
  with ``--racelines ../shared/tracks/racelines``, of the tracks' race lines).
- ``python benchmarks/steering_limit.py --track T runs/F [runs/F/sensors-f1tenth-real]``: for
  a comparison's step logs (``rkmpc compare --track T ... --out runs/F``), each controller's mean
  lateral error (m) over its first lap, near those places (within ``--window`` metres of path) and
  away from them, and the share of the LMPC -> ``nmpc-dynamic`` gap that ``rkmpc`` closes in each.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from compare_logs import first_laps

from rkmpc.sim.scenario import Scenario, load_scenario

#: Controllers shown, in this order, where their logs exist.
CONTROLLERS = ("lmpc", "lmpc-id", "nmpc-dynamic", "rkmpc")
#: Spacing (m) at which the path's curvature is sampled.
SPACING = 0.02
#: Share of the steering limit that marks a place of the path (``--fraction``).
FRACTION = 0.8
#: Metres of path around each such place counted as near it (``--window``).
WINDOW = 10.0


def path_wheel_angle(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Arc lengths (m) along the path and its kinematic wheel angle ``atan(L |kappa|)`` (rad) there."""
    path = scenario.reference.path
    s = np.arange(0.0, path.length, SPACING)
    kappa = np.abs(np.array([path.curvature(x) for x in s], dtype=float).ravel())
    return s, np.arctan(scenario.vehicle.wheelbase * kappa)


def places_near_limit(scenario: Scenario, fraction: float = FRACTION) -> np.ndarray:
    """Arc lengths (m) of the path where its wheel angle passes ``fraction`` of the steering limit."""
    s, wheel = path_wheel_angle(scenario)
    return s[wheel > fraction * scenario.vehicle.steering.max_angle]


def near(along: np.ndarray, places: np.ndarray, length: float, window: float = WINDOW) -> np.ndarray:
    """Whether each arc length ``along`` (m) is within ``window`` m of path of one of ``places``.

    Distances are taken around the closed path of length ``length``; no places, no step is near.
    """
    if places.size == 0:
        return np.zeros(len(along), dtype=bool)
    gap = np.abs(np.mod(along, length)[:, None] - places[None, :])
    return np.min(np.minimum(gap, length - gap), axis=1) < window


def tracks_table(tracks: list[str], vehicle: str, fraction: float, racelines: Path | None = None) -> str:
    """Markdown: per track, the largest wheel angle of its path and the metres near and past the limit.

    With ``racelines`` (a folder of TUM race lines named as the centre-line files), the path is the
    track's race line there.
    """
    lines = [
        f"| track | largest path wheel angle (rad) | path beyond {fraction:g} of the limit (m) "
        "| path beyond the limit (m) | length (m) |",
        "|---|---|---|---|---|",
    ]
    for track in tracks:
        raceline = None if racelines is None else racelines / Path(track).name
        scenario = load_scenario(track, vehicle=vehicle, raceline=raceline)
        limit = scenario.vehicle.steering.max_angle
        _, wheel = path_wheel_angle(scenario)
        lines.append(
            f"| {scenario.track.name} | {wheel.max():.3f} | {np.sum(wheel > fraction * limit) * SPACING:.2f} "
            f"| {np.sum(wheel > limit) * SPACING:.2f} | {scenario.reference.path.length:.0f} |"
        )
    return "\n".join(lines) + "\n"


def near_and_away(folder: Path, scenario: Scenario, fraction: float, window: float) -> str:
    """Markdown: each controller's lateral error near the places of the path close to the limit and away."""
    hot = places_near_limit(scenario, fraction)
    if hot.size == 0:
        return f"`{folder}`: the path stays below {fraction:g} of the steering limit\n"
    length = scenario.reference.path.length
    rows: dict[str, tuple[float, float, float, float]] = {}
    for name, log, first in first_laps(folder, CONTROLLERS):
        if first is None:
            continue
        close = near(log["s"][first], hot, length, window)
        error = np.abs(log["lateral_error"][first])
        rows[name] = (
            float(error.mean()),
            float(error[close].mean()),
            float(error[~close].mean()),
            close.mean(),
        )
    share = next(iter(rows.values()))[3] if rows else 0.0
    lines = [
        f"`{folder}` ({share:.0%} of the lap's steps within {window:g} m of path beyond {fraction:g} of the "
        "steering limit)",
        "",
        "| controller | lateral, lap (m) | near (m) | away (m) |",
        "|---|---|---|---|",
    ]
    lines += [f"| {n} | {lap:.4f} | {nr:.4f} | {aw:.4f} |" for n, (lap, nr, aw, _) in rows.items()]
    if {"lmpc", "nmpc-dynamic", "rkmpc"} <= rows.keys():
        closed = [
            (rows["lmpc"][i] - rows["rkmpc"][i]) / (rows["lmpc"][i] - rows["nmpc-dynamic"][i])
            for i in range(3)
        ]
        lines += ["", "gap closed by rkmpc: lap {:.0%}, near {:.0%}, away {:.0%}".format(*closed)]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, help="comparison output folders (with --track)")
    parser.add_argument("--track", help="the comparisons' track (built-in name or centre-line CSV)")
    parser.add_argument("--tracks", nargs="+", help="tracks for the table of path wheel angles")
    parser.add_argument("--racelines", type=Path, help="with --tracks: a folder of race lines to measure")
    parser.add_argument("--vehicle", default="f1tenth", help="vehicle preset (default: f1tenth)")
    parser.add_argument("--fraction", type=float, default=FRACTION, help="share of the steering limit (0.8)")
    parser.add_argument("--window", type=float, default=WINDOW, help="metres of path around each place (10)")
    args = parser.parse_args(argv)
    if not 0.0 < args.fraction <= 1.0 or args.window <= 0.0:
        parser.error("--fraction must be in (0, 1] and --window positive")
    if args.tracks:
        sys.stdout.write(tracks_table(args.tracks, args.vehicle, args.fraction, args.racelines) + "\n")
    if args.folders:
        if args.track is None:
            parser.error("comparison folders need --track")
        scenario = load_scenario(args.track, vehicle=args.vehicle)
        for folder in args.folders:
            sys.stdout.write(near_and_away(folder, scenario, args.fraction, args.window) + "\n")
    if not args.tracks and not args.folders:
        parser.error("give --tracks, or comparison folders with --track")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
