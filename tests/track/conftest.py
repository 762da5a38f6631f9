"""Shared fixtures and helpers for the track tests."""

from __future__ import annotations

from pathlib import Path as FilePath

import numpy as np
import pytest

from rkmpc.track import Path

TRACKS_DIR = FilePath(__file__).resolve().parents[2].parent / "shared" / "tracks"


@pytest.fixture
def tracks_dir() -> FilePath:
    """Folder of the TUM racetrack-database files; skips the test when absent."""
    if not (TRACKS_DIR / "centerlines").is_dir():
        pytest.skip(f"track data not found at {TRACKS_DIR}")
    return TRACKS_DIR


def stadium_points(straight: float, radius: float, spacing: float = 0.05) -> np.ndarray:
    """Counter-clockwise stadium: bottom straight from (0, 0) heading +x, top straight at y = 2 * radius."""
    pts = []
    n_straight = round(straight / spacing)
    n_arc = round(np.pi * radius / spacing)
    for k in range(n_straight):
        pts.append((k * spacing, 0.0))
    for k in range(n_arc):
        a = -np.pi / 2 + np.pi * k / n_arc
        pts.append((straight + radius * np.cos(a), radius + radius * np.sin(a)))
    for k in range(n_straight):
        pts.append((straight - k * spacing, 2 * radius))
    for k in range(n_arc):
        a = np.pi / 2 + np.pi * k / n_arc
        pts.append((radius * np.cos(a), radius + radius * np.sin(a)))
    return np.array(pts)


@pytest.fixture(scope="session")
def stadium() -> Path:
    """Stadium with 10 m straights 1 m apart (0.5 m radius hairpins), start mid-way along the bottom."""
    pts = stadium_points(10.0, 0.5)
    pts = np.roll(pts, -100, axis=0)  # start at x = 5 m on the bottom straight
    return Path.from_points(pts, name="stadium")
