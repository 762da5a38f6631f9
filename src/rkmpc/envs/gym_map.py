"""An rkmpc track as a map of the F1TENTH gym (v1.0.0): occupancy image, map YAML, centre and race line.

The F1TENTH gym loads a track from a folder ``NAME/`` holding (its ``Track.from_track_name``):

* ``NAME_map.png``: a single-channel image, white (255) free space and black (0) walls, at
  ``resolution`` metres a pixel, its bottom-left corner at ``origin`` (ROS ``map_server``'s
  convention; the gym flips the image so that its first row is the bottom and thresholds it at 128);
* ``NAME_map.yaml``: ``image``, ``resolution`` (m/pixel), ``origin`` (``[x, y, yaw]``, m, m, rad),
  ``negate``, ``occupied_thresh``, ``free_thresh``;
* ``NAME_centerline.csv``: the centre line as ``x_m, y_m, w_tr_right_m, w_tr_left_m`` (comma
  separated; the gym reads the first two columns, closes the loop itself and fits a spline);
* ``NAME_raceline.csv`` (optional): ``s_m; x_m; y_m; psi_rad; kappa_radpm; vx_mps; ax_mps2``
  (semicolon separated). Without it the gym's race line is its centre line.

:func:`gym_map` writes that folder from a :class:`~rkmpc.track.track.Track`: the free space is the
track between its boundaries (the ribbon of :meth:`Track.boundaries`, drawn as triangles, so a
bridge of a figure-8 is free where either pass is), everything else is wall, with ``margin`` metres
of wall around. With a :class:`~rkmpc.track.reference.Reference` it also writes the race line the
car tracks: its path with the speed profile (``psi_rad`` is the heading, 0 along +x, as the gym
computes it for its own lines). Nothing here needs the gym; :mod:`rkmpc.envs.f1tenth_gym` loads
the folder into it.
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from rkmpc.core.errors import ParameterError
from rkmpc.core.io import atomic_write, write_text_atomic
from rkmpc.core.validation import is_positive_number
from rkmpc.track.path import Path as TrackPath
from rkmpc.track.reference import Reference
from rkmpc.track.track import Track

__all__ = ["DEFAULT_RESOLUTION", "MAX_MAP_PIXELS", "gym_map", "gym_map_name", "occupancy_image"]

#: Metres a pixel of the occupancy image: the gym's own maps' 0.05 m.
DEFAULT_RESOLUTION = 0.05
#: Largest occupancy image written (pixels); a track at full scale needs a coarser resolution.
MAX_MAP_PIXELS = 64_000_000
#: Spacing of the centre- and race-line samples written (m), the gym's own 0.1 m.
LINE_SPACING = 0.1
# Free and occupied pixel values, and the thresholds of ROS map_server the gym's YAML carries.
_FREE, _WALL = 255, 0
_OCCUPIED_THRESH, _FREE_THRESH = 0.65, 0.196


def gym_map_name(name: str) -> str:
    """``name`` as the gym's map name: letters, digits, ``-`` and ``_`` only (others become ``_``)."""
    cleaned = re.sub(r"[^A-Za-z0-9_-]", "_", name.strip())
    if not cleaned:
        raise ParameterError(f"gym_map: the map name must have a letter or digit, got {name!r}")
    return cleaned


def gym_map(
    track: Track,
    folder: str | Path,
    *,
    reference: Reference | None = None,
    name: str | None = None,
    resolution: float = DEFAULT_RESOLUTION,
    margin: float = 1.0,
) -> Path:
    """Write ``track`` as an F1TENTH gym map in ``folder/NAME/``; returns that folder.

    Parameters
    ----------
    track : Track
        The track: its boundaries make the walls, its centre line the gym's centre line.
    folder : str or Path
        Folder the map's folder is written in (created when missing). Files already there are
        replaced, each written under a temporary name and renamed.
    reference : Reference, optional
        The path and speed profile a controller tracks (``scenario.reference``): written as the
        gym's race line. None: no race-line file (the gym uses its centre line).
    name : str or None
        Map name (:func:`gym_map_name`); None: the track's name.
    resolution : float
        Metres a pixel (> 0; :data:`DEFAULT_RESOLUTION`).
    margin : float
        Wall around the track's bounding box (m, >= 0).

    Returns
    -------
    Path
        ``folder/NAME``, holding ``NAME_map.png``, ``NAME_map.yaml``, ``NAME_centerline.csv`` and,
        with a reference, ``NAME_raceline.csv``.

    Raises
    ------
    ParameterError
        For a resolution or margin out of range, a name without letters, or an image larger than
        :data:`MAX_MAP_PIXELS` (choose a coarser resolution).
    """
    if not is_positive_number(resolution):
        raise ParameterError(f"gym_map: resolution must be finite and > 0 (m/pixel), got {resolution!r}")
    if not (isinstance(margin, int | float) and math.isfinite(margin) and margin >= 0.0):
        raise ParameterError(f"gym_map: margin must be finite and >= 0 (m), got {margin!r}")
    map_name = gym_map_name(track.name if name is None else name)
    out = Path(folder) / map_name
    image, origin = occupancy_image(track, resolution, margin)
    with atomic_write(out / f"{map_name}_map.png", "wb", suffix=".png") as handle:
        handle.write(_png_bytes(image))
    write_text_atomic(out / f"{map_name}_map.yaml", _map_yaml(f"{map_name}_map.png", resolution, origin))
    write_text_atomic(out / f"{map_name}_centerline.csv", _centerline_csv(track))
    if reference is not None:
        write_text_atomic(out / f"{map_name}_raceline.csv", _raceline_csv(reference))
    return out


def occupancy_image(track: Track, resolution: float, margin: float) -> tuple[np.ndarray, tuple[float, float]]:
    """The track's occupancy image (uint8, first row the top: free 255, wall 0) and its origin (m).

    The origin ``(x, y)`` is the world position of the image's bottom-left corner; pixel column
    ``c`` covers ``x`` in ``[x0 + c r, x0 + (c + 1) r)`` as the gym's ``xy_2_rc`` reads it.
    """
    corners = np.vstack([*track.boundaries(LINE_SPACING), track.centerline.sample(LINE_SPACING).xy])
    x0, y0 = corners.min(axis=0) - margin
    x1, y1 = corners.max(axis=0) + margin
    width, height = math.ceil((x1 - x0) / resolution), math.ceil((y1 - y0) / resolution)
    if width * height > MAX_MAP_PIXELS:
        raise ParameterError(
            f"gym_map: the map of {track.name!r} would be {width} x {height} pixels at {resolution} m a "
            f"pixel, more than {MAX_MAP_PIXELS}: choose a coarser resolution"
        )
    left, right = track.boundaries(0.5 * resolution)

    def pixels(points: np.ndarray) -> np.ndarray:
        """Image coordinates of world points: integer coordinates are pixel centres, rows go down."""
        u = (points[:, 0] - x0) / resolution - 0.5
        v = height - 0.5 - (points[:, 1] - y0) / resolution
        return np.column_stack([u, v])

    canvas = Image.new("L", (width, height), _WALL)
    draw = ImageDraw.Draw(canvas)
    lp, rp = pixels(left), pixels(right)
    ln, rn = np.roll(lp, -1, axis=0), np.roll(rp, -1, axis=0)
    for a, b, c, d in zip(lp, ln, rn, rp, strict=True):
        draw.polygon([tuple(a), tuple(b), tuple(c)], fill=_FREE)
        draw.polygon([tuple(a), tuple(c), tuple(d)], fill=_FREE)
    return np.asarray(canvas, dtype=np.uint8), (float(x0), float(y0))


def _png_bytes(image: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def _map_yaml(image: str, resolution: float, origin: tuple[float, float]) -> str:
    return (
        f"image: {image}\n"
        f"resolution: {resolution!r}\n"
        f"origin: [{origin[0]!r}, {origin[1]!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {_OCCUPIED_THRESH}\n"
        f"free_thresh: {_FREE_THRESH}\n"
    )


def _centerline_csv(track: Track) -> str:
    samples = track.centerline.sample(LINE_SPACING)
    rows = np.column_stack([samples.x, samples.y, track.width_right(samples.s), track.width_left(samples.s)])
    return _csv(rows, "x_m,y_m,w_tr_right_m,w_tr_left_m", ",")


def _raceline_csv(reference: Reference) -> str:
    path: TrackPath = reference.path
    samples = path.sample(LINE_SPACING)
    speed = np.asarray(reference.profile.speed(samples.s), dtype=float)
    # a = v dv/ds, the derivative taken around the closed lap.
    dv = (np.roll(speed, -1) - np.roll(speed, 1)) / (2.0 * samples.ds)
    rows = np.column_stack(
        [samples.s, samples.x, samples.y, samples.heading, samples.curvature, speed, speed * dv]
    )
    return _csv(rows, "s_m; x_m; y_m; psi_rad; kappa_radpm; vx_mps; ax_mps2", ";")


def _csv(rows: np.ndarray, header: str, delimiter: str) -> str:
    buffer = io.StringIO()
    np.savetxt(buffer, rows, delimiter=delimiter, header=header, fmt="%.6f")
    return buffer.getvalue()
