"""Transition data sets: what the car saw, what it was told, what it saw next.

A *transition* is the triple ``(o_k, u_k, o_{k+1})`` of one control period:
the observation at the start of the period, the command applied during it,
and the observation at its end. A :class:`TransitionDataset` stores ``N`` of
them as arrays, time (sample) first, in SI units, together with a JSON-able
metadata dictionary (vehicle, track, control period, seed, ...).

Transitions are grouped in *episodes*: within one episode, transitions with
consecutive indices are consecutive in time (``next_obs[k]`` is the
observation of ``obs[k + 1]``). Learning code that needs sequences (the
local-frame windows of :mod:`rkmpc.learning.data.augmentation`) never joins two
episodes.

Data sets are one ``.npz`` file (:meth:`TransitionDataset.save`), validated when read back
(:mod:`rkmpc.learning.data.checks`: errors name the file, the array and the problem).
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.io import atomic_write
from rkmpc.core.jsonutil import json_default
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.core.reading import read_npz
from rkmpc.learning.contract import CONTRACT_KEY, Provenance, contract_of
from rkmpc.learning.data.checks import (
    COMMAND_FIELDS,
    DT_RTOL,
    REQUIRED_COLUMNS,
    REQUIRED_OBSERVATION_FIELDS,
    Problem,
    check_arrays,
    check_metadata_contract,
    check_metadata_dt,
    check_units,
    plain_json,
)

__all__ = [
    "COMMAND_FIELDS",
    "FORMAT_VERSION",
    "REQUIRED_OBSERVATION_FIELDS",
    "StepTable",
    "TransitionDataset",
]

#: Version of the ``.npz`` layout written by :meth:`TransitionDataset.save`.
FORMAT_VERSION = 1
_ARRAY_NAMES = ("obs", "command", "next_obs", "episode")


class StepTable(Protocol):
    """What :meth:`TransitionDataset.from_log` reads: a :class:`rkmpc.sim.log.StepLog` or alike."""

    columns: tuple[str, ...]
    metadata: dict[str, Any]

    def __len__(self) -> int: ...
    def __getitem__(self, name: str) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class TransitionDataset:
    """``N`` transitions ``(o_k, u_k, o_{k+1})`` of a car, time first, SI units.

    The arrays are converted to ``float64`` (``episode`` to ``int64``) and
    made read-only.

    Parameters
    ----------
    obs : numpy.ndarray, shape (N, 7)
        Observation at the start of each step, columns
        :data:`rkmpc.core.observation.OBSERVATION_FIELDS`: ``x, y`` (m), ``yaw``
        (rad), ``speed`` (m/s), ``yaw_rate`` (rad/s), ``slip_angle`` (rad),
        ``steer_angle`` (rad). ``x, y, yaw, speed`` must be finite and
        ``speed >= 0``; the last three may be NaN (not measured).
    command : numpy.ndarray, shape (N, 2)
        Command applied during each step, ``[speed (m/s), steer (rad)]``; finite.
    next_obs : numpy.ndarray, shape (N, 7)
        Observation at the end of each step, same columns as ``obs``.
    dt : float
        Control period (s), > 0.
    episode : numpy.ndarray, shape (N,)
        Episode id of each transition, non-decreasing. Transitions with the
        same id and consecutive indices are consecutive in time.
    metadata : dict, optional
        JSON-able description (vehicle, track, scale, dt, seed, controller,
        laps, rkmpc version, source). When it holds ``"dt"``, that must equal
        ``dt``; when it holds a contract (:data:`rkmpc.learning.contract.CONTRACT_KEY`,
        see :meth:`with_contract`), that must be valid and agree on ``dt``.

    Raises
    ------
    ParameterError
        Naming the field and the problem, when any check fails.
    """

    obs: np.ndarray
    command: np.ndarray
    next_obs: np.ndarray
    dt: float
    episode: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        try:
            obs, command, next_obs, dt, episode = check_arrays(
                self.obs, self.command, self.next_obs, self.dt, self.episode
            )
            metadata = plain_json(self.metadata)
            check_metadata_dt(metadata, dt)
            check_metadata_contract(metadata, dt)
        except Problem as exc:
            raise ParameterError(f"TransitionDataset.{exc.field}: {exc.problem}") from None
        for array in (obs, command, next_obs, episode):
            array.flags.writeable = False
        object.__setattr__(self, "obs", obs)
        object.__setattr__(self, "command", command)
        object.__setattr__(self, "next_obs", next_obs)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "episode", episode)
        object.__setattr__(self, "metadata", metadata)

    def __len__(self) -> int:
        return int(self.obs.shape[0])

    def __repr__(self) -> str:
        n_episodes = len(np.unique(self.episode))
        return f"TransitionDataset(N={len(self)}, episodes={n_episodes}, dt={self.dt!r})"

    def poses(self) -> np.ndarray:
        """Poses at the start of each step, ``[x, y, yaw]`` (m, m, rad), shape (N, 3)."""
        return self.obs[:, :3]

    def next_poses(self) -> np.ndarray:
        """Poses at the end of each step, ``[x, y, yaw]`` (m, m, rad), shape (N, 3)."""
        return self.next_obs[:, :3]

    @property
    def contract(self) -> Provenance:
        """The car, period, track scale and state ranges the data were recorded with.

        A data set written before contracts knows only its ``dt``
        (``Provenance.recorded`` is False; checking it warns, never refuses).
        """
        return contract_of(self.metadata, dt=self.dt)

    def with_contract(self, made_with: Provenance) -> TransitionDataset:
        """The same data with ``made_with`` (car, scale) and the data's ``dt`` and ranges as its contract.

        The ranges are those of every observation field the data measure
        (:data:`~rkmpc.core.observation.OBSERVATION_FIELDS`, in ``obs`` and ``next_obs``).
        """
        states = np.concatenate([self.obs, self.next_obs])
        contract = replace(made_with, dt=self.dt, recorded=True).with_ranges(OBSERVATION_FIELDS, states)
        return TransitionDataset(
            obs=self.obs,
            command=self.command,
            next_obs=self.next_obs,
            dt=self.dt,
            episode=self.episode,
            metadata={**self.metadata, CONTRACT_KEY: contract.to_json()},
        )

    def content_hash(self) -> str:
        """SHA-256 (hex) of the arrays' bytes and ``dt``; metadata is not included."""
        digest = hashlib.sha256()
        for array in (self.obs, self.command, self.next_obs):
            digest.update(np.ascontiguousarray(array, dtype="<f8").tobytes())
        digest.update(np.ascontiguousarray(self.episode, dtype="<i8").tobytes())
        digest.update(repr(float(self.dt)).encode())
        return digest.hexdigest()

    @classmethod
    def from_log(
        cls, log: StepTable, metadata: dict[str, Any] | None = None, dt: float | None = None
    ) -> TransitionDataset:
        """Transitions of a closed-loop step log (:func:`rkmpc.sim.closed_loop.simulate`).

        Row ``k`` of the log becomes a transition when its command
        (``cmd_speed``, ``cmd_steer``) is finite, its and row ``k + 1``'s
        ``x, y, yaw, speed`` are finite (and the speed not negative: a car sliding
        backwards after a spin) and, when the log has a ``t`` column,
        ``t[k + 1] - t[k]`` equals ``dt``. The last row never has a
        successor. A normal run gives one episode; a log with holes (a row
        that cannot be used in the middle) gives one episode per unbroken
        stretch, so sequences never span a hole.

        Parameters
        ----------
        log : StepTable
            A :class:`rkmpc.sim.log.StepLog` or any table like it; needs the
            columns of :data:`~rkmpc.core.observation.OBSERVATION_FIELDS`,
            ``cmd_speed`` and ``cmd_steer``; ``t`` (s) is optional.
        metadata : dict, optional
            Merged over the log's own metadata (outcome, controller, seed).
        dt : float, optional
            Control period (s); by default the median step of the ``t`` column.

        Returns
        -------
        TransitionDataset

        Raises
        ------
        ParameterError
            When columns are missing, ``dt`` cannot be found, or no row makes
            a transition.
        """
        missing = [c for c in (*OBSERVATION_FIELDS, "cmd_speed", "cmd_steer") if c not in log.columns]
        if missing:
            raise ParameterError(f"TransitionDataset.from_log: the log lacks the columns {missing}")
        n_rows = len(log)
        obs_all = np.stack([np.asarray(log[c], dtype=float) for c in OBSERVATION_FIELDS], axis=1)
        cmd_all = np.stack([np.asarray(log["cmd_speed"]), np.asarray(log["cmd_steer"])], axis=1)
        times = np.asarray(log["t"], dtype=float) if "t" in log.columns else None
        if dt is None:
            steps = np.diff(times) if times is not None else np.empty(0)
            steps = steps[np.isfinite(steps) & (steps > 0)]
            if steps.size == 0:
                raise ParameterError(
                    "TransitionDataset.from_log: dt not given and the log has no usable 't' column"
                )
            dt = float(np.median(steps))
        if not (math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f"TransitionDataset.from_log: dt must be finite and > 0, got {dt!r}")
        if n_rows < 2:
            raise ParameterError(f"TransitionDataset.from_log: the log has {n_rows} row(s); need at least 2")
        row_ok = np.all(np.isfinite(obs_all[:, REQUIRED_COLUMNS]), axis=1)
        # A spun car sliding backwards (speed along its heading below 0) is no transition the
        # models describe: such rows are holes, as non-finite ones are.
        row_ok &= ~(obs_all[:, OBSERVATION_FIELDS.index("speed")] < 0.0)
        usable = row_ok[:-1] & row_ok[1:] & np.all(np.isfinite(cmd_all[:-1]), axis=1)
        if times is not None:
            usable &= np.isclose(np.diff(times), dt, rtol=1e-6, atol=1e-9)
        rows = np.flatnonzero(usable)
        if rows.size == 0:
            raise ParameterError("TransitionDataset.from_log: no row of the log makes a transition")
        starts = np.ones(rows.size, dtype=bool)
        starts[1:] = np.diff(rows) != 1
        episode = np.cumsum(starts).astype(np.int64) - 1
        meta: dict[str, Any] = dict(log.metadata)
        if metadata:
            meta.update(metadata)
        meta["dt"] = dt
        meta.setdefault("source", "log")
        data = cls(
            obs=obs_all[rows],
            command=cmd_all[rows],
            next_obs=obs_all[rows + 1],
            dt=dt,
            episode=episode,
            metadata=meta,
        )
        # A run's log records the car, period and scale (rkmpc.sim.run.drive): add the data's ranges.
        return data.with_contract(data.contract) if data.contract.recorded else data

    @classmethod
    def concatenate(cls, parts: Sequence[TransitionDataset]) -> TransitionDataset:
        """Join data sets end to end; episodes are renumbered ``0, 1, 2, ...``.

        Parameters
        ----------
        parts : sequence of TransitionDataset
            At least one; all with the same ``dt``.

        Returns
        -------
        TransitionDataset
            Metadata ``{"source": "concatenate", "dt": dt, "parts": [...]}``
            with the parts' metadata in order and, when every part has a contract,
            their merged contract (:meth:`rkmpc.learning.contract.Provenance.merged`).
        """
        if len(parts) == 0:
            raise ParameterError("TransitionDataset.concatenate: no data sets given")
        dt = parts[0].dt
        for i, part in enumerate(parts):
            if not math.isclose(part.dt, dt, rel_tol=DT_RTOL, abs_tol=0.0):
                raise ParameterError(
                    f"TransitionDataset.concatenate: part {i} has dt = {part.dt!r} s, part 0 has {dt!r} s"
                )
        episodes = []
        offset = 0
        for part in parts:
            _, local = np.unique(part.episode, return_inverse=True)
            episodes.append(local.astype(np.int64) + offset)
            offset += int(local.max()) + 1 if local.size else 0
        metadata: dict[str, Any] = {"source": "concatenate", "dt": dt, "parts": [p.metadata for p in parts]}
        contracts = [part.contract for part in parts]
        if all(c.recorded for c in contracts):
            metadata[CONTRACT_KEY] = functools.reduce(Provenance.merged, contracts).to_json()
        return cls(
            obs=np.concatenate([p.obs for p in parts]),
            command=np.concatenate([p.command for p in parts]),
            next_obs=np.concatenate([p.next_obs for p in parts]),
            dt=dt,
            episode=np.concatenate(episodes),
            metadata=metadata,
        )

    def save(self, path: str | Path) -> None:
        """Write the data set as one ``.npz`` file.

        The archive holds the arrays ``obs``, ``command``, ``next_obs``,
        ``episode``, ``dt`` (0-d), ``metadata`` (0-d string, JSON) and
        ``format`` (0-d int, :data:`FORMAT_VERSION`). It is written to a
        temporary file in the same folder, then renamed into place, so a
        crash never leaves a half-written file under ``path``.

        Parameters
        ----------
        path : str or Path
            Destination; folders are created. Written as given (no ``.npz``
            suffix is added).
        """
        with atomic_write(path, "wb") as handle:
            np.savez_compressed(
                handle,
                obs=self.obs,
                command=self.command,
                next_obs=self.next_obs,
                episode=self.episode,
                dt=np.float64(self.dt),
                metadata=np.str_(json.dumps(self.metadata, default=json_default)),
                format=np.int64(FORMAT_VERSION),
            )

    @classmethod
    def load(cls, path: str | Path) -> TransitionDataset:
        """Read and validate a file written by :meth:`save`.

        Parameters
        ----------
        path : str or Path
            The ``.npz`` file.

        Returns
        -------
        TransitionDataset

        Raises
        ------
        InputFileError
            Naming the file, the array at fault and the problem: missing
            file, not an ``.npz`` archive (corrupted or truncated), unknown
            format version, missing array, wrong shape, non-finite required
            values, negative speed, angles that look like degrees
            (``|yaw| > 100`` rad, ``|steer| > 1.5`` rad), or a ``dt`` that
            disagrees with the metadata.
        """
        path = Path(path)
        if not path.exists():
            raise InputFileError(path, "file not found")
        if not path.is_file():
            raise InputFileError(path, "not a file")
        contents = read_npz(path)
        if "format" not in contents:
            raise InputFileError(path, "missing array 'format': not a transition data set", "format")
        fmt = contents["format"]
        if fmt.shape != () or fmt.dtype.kind not in "iu" or int(fmt) != FORMAT_VERSION:
            raise InputFileError(
                path, f"unknown format version {fmt.tolist()!r}; this rkmpc reads {FORMAT_VERSION}", "format"
            )
        for name in (*_ARRAY_NAMES, "dt", "metadata"):
            if name not in contents:
                raise InputFileError(path, f"missing array {name!r}", name)
        dt_arr = contents["dt"]
        if dt_arr.shape != () or dt_arr.dtype.kind not in "fiu":
            raise InputFileError(path, f"must be a number, got shape {dt_arr.shape} {dt_arr.dtype}", "dt")
        meta_arr = contents["metadata"]
        if meta_arr.shape != () or meta_arr.dtype.kind != "U":
            raise InputFileError(path, "must be a JSON string", "metadata")
        try:
            metadata = json.loads(str(meta_arr))
        except json.JSONDecodeError as exc:
            raise InputFileError(path, f"invalid JSON: {exc}", "metadata") from None
        if not isinstance(metadata, dict):
            raise InputFileError(path, "must be a JSON object", "metadata")
        try:
            obs, command, next_obs, dt, episode = check_arrays(
                contents["obs"], contents["command"], contents["next_obs"], dt_arr, contents["episode"]
            )
            check_metadata_dt(metadata, dt)
            check_metadata_contract(metadata, dt)
            check_units(obs, command, next_obs)
        except Problem as exc:
            raise InputFileError(path, exc.problem, exc.field) from None
        return cls(obs=obs, command=command, next_obs=next_obs, dt=dt, episode=episode, metadata=metadata)
