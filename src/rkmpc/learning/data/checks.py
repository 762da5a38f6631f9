"""Validation of the arrays and metadata of a transition data set (:mod:`rkmpc.learning.data.dataset`).

Each check raises :class:`Problem` naming the field at fault and the problem; the data set turns it
into a :class:`~rkmpc.core.errors.ParameterError` (when built in memory) or an
:class:`~rkmpc.core.errors.InputFileError` naming the file (when read back). Units are SI: positions
in m, angles in rad, speeds in m/s, the control period in s.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import json_default
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.contract import CONTRACT_KEY, Provenance

__all__ = [
    "COMMAND_FIELDS",
    "DT_RTOL",
    "MAX_STEER",
    "MAX_YAW",
    "REQUIRED_COLUMNS",
    "REQUIRED_OBSERVATION_FIELDS",
    "Problem",
    "check_arrays",
    "check_metadata_contract",
    "check_metadata_dt",
    "check_units",
    "float_array",
    "plain_json",
]

#: Names of the columns of ``TransitionDataset.command``.
COMMAND_FIELDS: tuple[str, ...] = ("speed", "steer")
#: Observation columns that must be finite; the others may be NaN (not measured).
REQUIRED_OBSERVATION_FIELDS: tuple[str, ...] = ("x", "y", "yaw", "speed")
#: Indices of :data:`REQUIRED_OBSERVATION_FIELDS` in :data:`~rkmpc.core.observation.OBSERVATION_FIELDS`.
REQUIRED_COLUMNS = tuple(OBSERVATION_FIELDS.index(name) for name in REQUIRED_OBSERVATION_FIELDS)
#: Above these magnitudes an angle is taken to be in degrees (rad).
MAX_YAW = 100.0
MAX_STEER = 1.5
#: Relative tolerance when comparing control periods.
DT_RTOL = 1e-9

_N_OBS = len(OBSERVATION_FIELDS)
_N_CMD = len(COMMAND_FIELDS)
_SPEED = OBSERVATION_FIELDS.index("speed")
_YAW = OBSERVATION_FIELDS.index("yaw")
_STEER_ANGLE = OBSERVATION_FIELDS.index("steer_angle")


class Problem(Exception):
    """One validation failure: the ``field`` at fault (``"obs.speed"``, ``"dt"``, ...) and the ``problem``."""

    def __init__(self, field: str, problem: str) -> None:
        super().__init__(f"{field}: {problem}")
        self.field = field
        self.problem = problem


def plain_json(metadata: Any) -> dict[str, Any]:
    """``metadata`` as plain JSON types (numpy scalars become Python numbers)."""
    if not isinstance(metadata, dict):
        raise Problem("metadata", f"must be a dict, got {type(metadata).__name__}")
    try:
        plain = json.loads(json.dumps(metadata, default=json_default, allow_nan=True))
    except (TypeError, ValueError) as exc:
        raise Problem("metadata", f"not JSON-able: {exc}") from None
    return dict(plain)


def float_array(value: Any, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float64 copy of shape ``(N, *shape_tail)``; raise :class:`Problem` naming ``name``."""
    array = np.asarray(value)
    if array.dtype.kind not in "fiu":
        raise Problem(name, f"must hold real numbers, got dtype {array.dtype}")
    array = np.array(array, dtype=np.float64)
    expected = "(N, " + ", ".join(str(n) for n in shape_tail) + ")"
    if array.ndim != 1 + len(shape_tail) or array.shape[1:] != shape_tail:
        raise Problem(name, f"shape {array.shape}, expected {expected}")
    return array


def check_arrays(
    obs: Any, command: Any, next_obs: Any, dt: Any, episode: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """Validate and convert the arrays of a data set.

    Parameters
    ----------
    obs, next_obs : array_like, shape (N, 7)
        Observations (columns of :data:`~rkmpc.core.observation.OBSERVATION_FIELDS`, SI units).
    command : array_like, shape (N, 2)
        Commands ``[speed (m/s), steer (rad)]``.
    dt : float
        Control period (s).
    episode : array_like, shape (N,)
        Episode ids, whole numbers, non-decreasing.

    Returns
    -------
    obs, command, next_obs : ndarray, float64
    dt : float
    episode : ndarray, int64

    Raises
    ------
    Problem
        For the first check that fails, in the order of the parameters (shapes, then episodes,
        ``dt``, and the values).
    """
    obs_a = float_array(obs, "obs", (_N_OBS,))
    n = obs_a.shape[0]
    cmd_a = float_array(command, "command", (_N_CMD,))
    next_a = float_array(next_obs, "next_obs", (_N_OBS,))
    for name, array in (("command", cmd_a), ("next_obs", next_a)):
        if array.shape[0] != n:
            raise Problem(name, f"{array.shape[0]} rows but obs has {n}")
    ep_i = _episode_ids(episode, n)
    try:
        dt_f = float(dt)
    except (TypeError, ValueError):
        raise Problem("dt", f"must be a number, got {dt!r}") from None
    if not (math.isfinite(dt_f) and dt_f > 0.0):
        raise Problem("dt", f"must be finite and > 0, got {dt!r}")
    _check_values(obs_a, cmd_a, next_a)
    return obs_a, cmd_a, next_a, dt_f, ep_i


def _episode_ids(episode: Any, n: int) -> np.ndarray:
    """Episode ids as int64, shape (n,): whole numbers, non-decreasing; raise :class:`Problem`."""
    ep = np.asarray(episode)
    if ep.dtype.kind not in "iu" and not (ep.dtype.kind == "f" and np.all(np.isfinite(ep))):
        raise Problem("episode", f"must hold integers, got dtype {ep.dtype}")
    if ep.shape != (n,):
        raise Problem("episode", f"shape {ep.shape}, expected ({n},)")
    ep_i = ep.astype(np.int64)
    if ep.dtype.kind == "f" and not np.array_equal(ep_i, ep):
        raise Problem("episode", "must hold whole numbers")
    if n > 1 and np.any(np.diff(ep_i) < 0):
        first = int(np.argmax(np.diff(ep_i) < 0)) + 1
        raise Problem("episode", f"must not decrease (row {first})")
    return ep_i


def _check_values(obs: np.ndarray, command: np.ndarray, next_obs: np.ndarray) -> None:
    """Required observation columns and commands finite, speeds >= 0 (m/s); raise :class:`Problem`."""
    for name, array in (("obs", obs), ("next_obs", next_obs)):
        for col in REQUIRED_COLUMNS:
            bad = ~np.isfinite(array[:, col])
            if np.any(bad):
                raise Problem(
                    f"{name}.{OBSERVATION_FIELDS[col]}",
                    f"{int(bad.sum())} non-finite value(s), first at row {int(np.argmax(bad))}",
                )
        negative = array[:, _SPEED] < 0.0
        if np.any(negative):
            row = int(np.argmax(negative))
            raise Problem(f"{name}.speed", f"negative speed {array[row, _SPEED]!r} m/s at row {row}")
    for col, cname in enumerate(COMMAND_FIELDS):
        bad = ~np.isfinite(command[:, col])
        if np.any(bad):
            raise Problem(
                f"command.{cname}",
                f"{int(bad.sum())} non-finite value(s), first at row {int(np.argmax(bad))}",
            )


def check_metadata_dt(metadata: dict[str, Any], dt: float) -> None:
    """A ``"dt"`` in ``metadata`` must equal ``dt`` (s) to :data:`DT_RTOL`; raise :class:`Problem`."""
    if "dt" not in metadata:
        return
    try:
        meta_dt = float(metadata["dt"])
    except (TypeError, ValueError):
        raise Problem("metadata.dt", f"must be a number, got {metadata['dt']!r}") from None
    if not math.isclose(meta_dt, dt, rel_tol=DT_RTOL, abs_tol=0.0):
        raise Problem("dt", f"dt = {dt!r} s but the metadata says {meta_dt!r} s")


def check_metadata_contract(metadata: dict[str, Any], dt: float) -> None:
    """The contract in ``metadata`` (``CONTRACT_KEY``), if any: valid and agreeing on ``dt``."""
    if CONTRACT_KEY not in metadata:
        return
    try:
        contract = Provenance.from_json(metadata[CONTRACT_KEY])
    except ParameterError as exc:
        raise Problem(f"metadata.{CONTRACT_KEY}", str(exc)) from None
    if contract.dt is not None and not math.isclose(contract.dt, dt, rel_tol=DT_RTOL, abs_tol=0.0):
        raise Problem(f"metadata.{CONTRACT_KEY}.dt", f"dt = {dt!r} s but the contract says {contract.dt!r} s")


def check_units(obs: np.ndarray, command: np.ndarray, next_obs: np.ndarray) -> None:
    """Catch angles stored in degrees; raise :class:`Problem`."""
    for name, array in (("obs", obs), ("next_obs", next_obs)):
        if array.shape[0] == 0:
            continue
        yaw = np.abs(array[:, _YAW])
        if np.max(yaw) > MAX_YAW:
            raise Problem(
                f"{name}.yaw",
                f"|yaw| reaches {np.max(yaw):.4g} rad (> {MAX_YAW:g} rad): looks like degrees? "
                "Angles must be in radians (wrap the heading if it accumulates many turns)",
            )
        steer = np.abs(array[:, _STEER_ANGLE])
        if np.any(steer[np.isfinite(steer)] > MAX_STEER):
            raise Problem(
                f"{name}.steer_angle",
                f"|steer_angle| reaches {np.nanmax(steer):.4g} rad (> {MAX_STEER:g} rad): "
                "looks like degrees?",
            )
    if command.shape[0] and np.max(np.abs(command[:, 1])) > MAX_STEER:
        raise Problem(
            "command.steer",
            f"|steer| reaches {np.max(np.abs(command[:, 1])):.4g} rad (> {MAX_STEER:g} rad): "
            "looks like degrees?",
        )
