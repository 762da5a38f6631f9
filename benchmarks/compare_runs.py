"""Compare the figures of two runs of the same commands (before and after a change).

Each run folder holds ``demo/results.json`` (``rkmpc compare --track builtin``) and, optionally,
``study3/study_tracks.json`` (``rkmpc study tracks ...``). For every (track, controller) the script
prints the largest relative difference of the lap figures (step times excluded: they are
wall-clock) and a Markdown table of the main figures before and after.

Run: ``python benchmarks/compare_runs.py BEFORE_DIR AFTER_DIR``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from rkmpc.analysis.metrics import METRIC_KEYS

#: Lap figures compared: every metric but the step times (wall-clock).
KEYS = tuple(key for key in METRIC_KEYS if not key.startswith("solve_ms"))


def relative(a: Any, b: Any) -> float:
    """0 for equal values, the relative difference of numbers, infinity for other mismatches."""
    if a == b:
        return 0.0
    if a is None or b is None or isinstance(a, bool) or isinstance(b, bool):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def runs(folder: Path) -> list[tuple[str, dict[str, Any]]]:
    """(track, metrics by controller) of the demo and of every study job in ``folder``."""
    out = [("builtin (demo)", json.loads((folder / "demo" / "results.json").read_text())["controllers"])]
    study = folder / "study3" / "study_tracks.json"
    if study.exists():
        out += [(job["track"], job["controllers"]) for job in json.loads(study.read_text())["jobs"]]
    return out


def _fmt(value: Any, spec: str) -> str:
    if value is None:
        return "-"
    return str(value) if isinstance(value, bool | int) else format(value, spec)


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args()
    pairs = list(zip(runs(args.before), runs(args.after), strict=True))
    for (track, before), (_, after) in pairs:
        for name, m in before.items():
            worst = max((relative(m[k], after[name][k]), k) for k in KEYS)
            print(f"{track:16s} {name:14s} largest relative difference {worst[0]:.3g} ({worst[1]})")
    print()
    head = ["track", "controller", "lateral (m) before", "after", "heading (rad) before", "after"]
    print("| " + " | ".join([*head, "wheel rate (rad/s) before", "after"]) + " |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for (track, before), (_, after) in pairs:
        for name, m in before.items():
            a = after[name]
            cells = [track, name]
            for key in ("lateral_error_mean_m", "heading_error_mean_rad", "steer_rate_mean_rad_s"):
                cells += [_fmt(m[key], ".6f"), _fmt(a[key], ".6f")]
            print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
