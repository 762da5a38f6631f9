"""Synthetic CSV logs in the FrictionMaps logger's layout, with known defects (for the CSV-import tests).

Imported by ``tests/learning/conftest.py`` and ``tests/cli/test_cli_csv.py``; the real logs are read in
place from ``../shared/real/f1tenth-car`` (:data:`REAL_LOGS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The real car's logs (runs DS2, DS3), beside the repository; never copied.
REAL_LOGS = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "f1tenth-car"


@dataclass(frozen=True)
class Drive:
    """A synthetic run in the FrictionMaps logger's layout, with the defects to put in.

    The car drives a circle (``speed`` m/s, ``yaw_rate`` rad/s); ``reverse`` (start, length) s
    drives it backwards at 1 m/s; ``gap`` (start, length) s drops every signal; ``jump`` (time s,
    metres) moves every later pose by that much in x; the speed sensor reads ``speed_scale``
    times the true speed; the IMU's ``wz`` is in deg/s.
    """

    seconds: float = 20.0
    speed: float = 2.0
    yaw_rate: float = 0.5
    speed_scale: float = 1.0
    gap: tuple[float, float] | None = None
    jump: tuple[float, float] | None = None
    reverse: tuple[float, float] | None = None
    seed: int = 0


def _stamps(rng: np.random.Generator, seconds: float, start: float) -> np.ndarray:
    steps = rng.uniform(0.018, 0.032, size=int(seconds / 0.018) + 2)
    t = start + np.cumsum(steps)
    return t[t < seconds]


def write_drive(folder: Path, drive: Drive | None = None, epoch: float = 1_650_000_000.0) -> Path:
    """Write the five CSV files of ``drive`` into ``folder`` (module docstring of :class:`Drive`)."""
    drive = drive or Drive()
    rng = np.random.default_rng(drive.seed)
    fine = np.arange(0.0, drive.seconds + 0.5, 1e-3)
    v = np.full(fine.shape, drive.speed)
    if drive.reverse is not None:
        start, length = drive.reverse
        v[(fine >= start) & (fine < start + length)] = -1.0
    yaw = drive.yaw_rate * fine
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * np.cos(yaw[:-1]) * 1e-3)])
    y = np.concatenate([[0.0], np.cumsum(v[:-1] * np.sin(yaw[:-1]) * 1e-3)])

    def at(t: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.interp(t, fine, values)

    def kept(t: np.ndarray) -> np.ndarray:
        if drive.gap is None:
            return t
        start, length = drive.gap
        return t[(t < start) | (t > start + length)]

    folder.mkdir(parents=True, exist_ok=True)
    tp = kept(_stamps(rng, drive.seconds, 0.0))
    px = at(tp, x) + rng.normal(0.0, 0.005, tp.size)
    if drive.jump is not None:
        px = px + np.where(tp >= drive.jump[0], drive.jump[1], 0.0)
    py = at(tp, y) + rng.normal(0.0, 0.005, tp.size)
    half = at(tp, yaw) / 2
    zeros = np.zeros(tp.size)
    _write(folder / "pfPoseData.csv", epoch, tp, {"x": px, "y": py, "q.x": zeros, "q.y": zeros,
           "q.z": np.sin(half), "q.w": np.cos(half)})  # fmt: skip
    to = kept(_stamps(rng, drive.seconds, 0.005))
    vx = at(to, v) * drive.speed_scale + rng.normal(0.0, 0.01, to.size)
    _write(folder / "odomData.csv", epoch, to, {"vx": vx, "vy": np.zeros(to.size), "wx": vx})
    ti = kept(_stamps(rng, drive.seconds, 0.002))
    wz = math.degrees(drive.yaw_rate) + rng.normal(0.0, 0.5, ti.size)
    _write(folder / "imuData.csv", epoch, ti, {"ax": np.zeros(ti.size), "wz": wz})
    tc = kept(_stamps(rng, drive.seconds, 0.001))
    steer = np.full(tc.size, math.atan(0.33 * drive.yaw_rate / drive.speed))
    _write(folder / "commandData.csv", epoch, tc, {"V": at(tc, v), "delta": steer})
    return folder


def _write(path: Path, epoch: float, t: np.ndarray, columns: dict[str, np.ndarray]) -> None:
    """A CSV in the logger's form: an unnamed index, ``s`` and ``ns``, then the columns."""
    stamp = np.round((epoch + t) * 1e9).astype(np.int64)
    lines = [",s,ns," + ",".join(columns)]
    for k, ns in enumerate(stamp):
        values = ",".join(repr(float(c[k])) for c in columns.values())
        lines.append(f"0,{ns // 1_000_000_000},{ns % 1_000_000_000},{values}")
    path.write_text("\n".join(lines) + "\n")
