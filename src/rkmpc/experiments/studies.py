"""Studies over many independent runs: every track, and the data-volume figure.

:func:`study_tracks`
    The learned comparison of :func:`rkmpc.experiments.learned.evaluate_track`
    on a list of tracks and seeds, one parallel job per (track, seed),
    summarised per controller over all of them: mean and spread of every lap
    metric and of its change in % against a baseline controller (``lmpc``)
    on the same track and seed.
:func:`study_data`
    The paper's data-volume figure (Sec. V, "RKMPC uses about 8000 data
    points while KMPC needs 50000 or more"): RKMPC and KMPC trained on a
    growing number of samples, one parallel job per (controller, size, seed),
    each driving one lap of one track.

Both run through :func:`rkmpc.experiments.parallel.run_jobs` (``n_jobs``,
``backend``, ``address``), record failed jobs instead of stopping (the
failure message is in the result), and return a JSON-ready dict holding
their configuration, seeds and package versions, enough to run them again.
:func:`tracks_markdown` and :func:`data_markdown` render the results;
:func:`rkmpc.analysis.study_plots.plot_data_study` plots the data study.

Statistics: ``n`` values, their ``mean``, sample standard deviation ``std``
(``ddof=1``; None for fewer than two values), ``min`` and ``max``; None
everywhere for no values.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import numbers
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.analysis.metrics import METRIC_KEYS
from rkmpc.errors import ParameterError
from rkmpc.experiments.learned import LEARNED_CONTROLLERS, TrackStudy, evaluate_track
from rkmpc.experiments.parallel import BACKENDS, Job, JobOutcome, run_jobs
from rkmpc.experiments.runner import RunSpec, run_controller, versions

#: Lap metrics summarised by the studies: the numeric ones of
#: :data:`rkmpc.analysis.metrics.METRIC_KEYS`, in its order.
TRACK_METRICS = tuple(k for k in METRIC_KEYS if k not in ("completed", "steps", "lateral_accel_max_m_s2"))

#: Metrics whose change against the baseline is reported (not ``progress``:
#: both laps are complete where a change is computed).
CHANGE_METRICS = tuple(m for m in TRACK_METRICS if m != "progress")

#: Training-sample targets of the data study (augmented transitions, the paper's M = N x N_p).
DEFAULT_SIZES = (1000, 2000, 4000, 8000, 16000, 32000, 50000)

#: Controllers of the data study and the model kind each is trained as.
DATA_CONTROLLERS = {"rkmpc": "residual", "kmpc": "koopman"}


# ---------------------------------------------------------------------------
# helpers


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _positive_real(value: Any, upper: float = math.inf) -> bool:
    """True for a finite number in ``(0, upper]`` (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return False
    f = float(value)
    return math.isfinite(f) and 0.0 < f <= upper


def _int_tuple(name: str, values: Any, *, minimum: int) -> tuple[int, ...]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
        raise ParameterError(f"{name} must be a sequence of integers, got {values!r}")
    out = tuple(values)
    if not out:
        raise ParameterError(f"{name} must not be empty")
    for v in out:
        if not _is_int(v) or v < minimum:
            raise ParameterError(f"{name} must hold integers >= {minimum}, got {v!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"{name} must not repeat values, got {list(out)}")
    return tuple(int(v) for v in out)


def _str_tuple(name: str, values: Any) -> tuple[str, ...]:
    if isinstance(values, str):
        values = values.split(",")
    if not isinstance(values, Iterable):
        raise ParameterError(f"{name} must be a sequence of strings, got {values!r}")
    out = tuple(values)
    if not out or not all(isinstance(v, str) and v for v in out):
        raise ParameterError(f"{name} must be a non-empty sequence of non-empty strings, got {values!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"{name} must not repeat values, got {list(out)}")
    return out


def _check_track(spec: str) -> None:
    from rkmpc.track.builtin import list_builtin_tracks

    if spec in list_builtin_tracks():
        return
    if not Path(spec).is_file():
        raise ParameterError(
            f"track {spec!r} is neither a built-in track ({', '.join(list_builtin_tracks())}) "
            "nor an existing centre-line CSV file"
        )


def _check_common(obj: Any) -> None:
    """Scale and vehicle of a study configuration."""
    from rkmpc.scenario import VEHICLES

    if obj.scale is not None and not _positive_real(obj.scale):
        raise ParameterError(f"scale must be a positive number or None, got {obj.scale!r}")
    if obj.vehicle not in VEHICLES:
        raise ParameterError(f"vehicle must be one of {sorted(VEHICLES)}, got {obj.vehicle!r}")


def _track_label(spec: str) -> str:
    """Name of a track spec as results show it (built-in name or file stem)."""
    return Path(spec).stem if spec.lower().endswith(".csv") else spec


def expand_tracks(items: Iterable[str | Path]) -> tuple[str, ...]:
    """Track specs from names, CSV files and folders of CSV files.

    Parameters
    ----------
    items : iterable of str or Path
        Built-in track names, centre-line CSV paths, or folders (each gives
        its ``*.csv`` files, sorted by name).

    Returns
    -------
    tuple of str
        Built-in names and file paths, in the order given.
    """
    out: list[str] = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            found = sorted(str(p) for p in path.glob("*.csv"))
            if not found:
                raise ParameterError(f"track folder {path} holds no *.csv file")
            out.extend(found)
        else:
            out.append(str(item))
    return tuple(out)


def stats(values: Iterable[float | None]) -> dict[str, float | int | None]:
    """``n``, ``mean``, ``std`` (sample, ``ddof=1``), ``min``, ``max`` of the finite values.

    None and non-finite values are left out; ``std`` is None for fewer than two
    values and every statistic is None for none.
    """
    arr = np.array(
        [float(v) for v in values if v is not None and math.isfinite(float(v))],
        dtype=float,
    )
    n = int(arr.size)
    if n == 0:
        return {"n": 0, "mean": None, "std": None, "min": None, "max": None}
    return {
        "n": n,
        "mean": float(arr.mean()),
        "std": float(arr.std(ddof=1)) if n > 1 else None,
        "min": float(arr.min()),
        "max": float(arr.max()),
    }


def change_pct(value: float | None, base: float | None) -> float | None:
    """``100 * (value - base) / base``; None where either is missing or ``base`` is 0."""
    if value is None or base is None:
        return None
    value, base = float(value), float(base)
    if not (math.isfinite(value) and math.isfinite(base)) or base == 0.0:
        return None
    return 100.0 * (value - base) / base


def to_json_ready(obj: Any) -> Any:
    """Plain JSON types: dataclasses as dicts, numpy values as numbers and lists,
    paths as strings, NaN and infinities as None, unknown objects as their ``repr``."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_json_ready(asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): to_json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_json_ready(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, numbers.Integral):
        return int(obj)
    if isinstance(obj, numbers.Real):
        f = float(obj)
        return f if math.isfinite(f) else None
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    return repr(obj)


def study_versions() -> dict[str, str]:
    """:func:`rkmpc.experiments.runner.versions` plus the learning and parallel packages."""
    out = dict(versions())
    for name in ("torch", "joblib", "dask", "distributed", "ray"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def _check_parallel(n_jobs: int, backend: str) -> None:
    if backend not in BACKENDS:
        raise ParameterError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if not _is_int(n_jobs) or n_jobs == 0 or n_jobs < -1:
        raise ParameterError(f"n_jobs must be a positive integer or -1, got {n_jobs!r}")


def _fmt(value: float | None, spec: str = ".4f") -> str:
    return "-" if value is None else format(value, spec)


def _fmt_stats(s: Mapping[str, Any], spec: str = ".4f", pct: bool = False) -> str:
    """``mean ± std [min, max]`` of a statistics dict."""
    if not s or s.get("mean") is None:
        return "-"
    sign = "+" if pct else ""
    unit = "%" if pct else ""
    text = f"{s['mean']:{sign}{spec}}{unit}"
    if s.get("std") is not None:
        text += f" ± {s['std']:{spec}}"
    if s.get("n", 0) > 1:
        text += f" [{s['min']:{sign}{spec}}, {s['max']:{sign}{spec}}]"
    return text


# ---------------------------------------------------------------------------
# every track


@dataclass(frozen=True)
class TracksStudyConfig:
    """Settings of :func:`study_tracks`.

    Parameters
    ----------
    tracks : sequence of str
        Built-in track names or centre-line CSV paths (see :func:`expand_tracks`).
    controllers : sequence of str
        Controllers each job drives (``TrackStudy.controllers``); a
        comma-separated string is accepted.
    seeds : sequence of int
        Seeds (>= 0); one job per (track, seed). The seed sets the data
        collection, training and the runs (``TrackStudy.seed``).
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    kmpc_model : str or None
        Path of a trained ``koopman`` model for ``kmpc`` (``TrackStudy.kmpc_model``).
    baseline : str or None
        Controller the changes in % are measured against (must be in
        ``controllers``); None for no changes.
    study_options : mapping
        Further keyword arguments of :class:`rkmpc.experiments.learned.TrackStudy`
        (any of its fields other than the ones above), passed to every job;
        values must be picklable.
    """

    tracks: Sequence[str]
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    seeds: Sequence[int] = (0,)
    scale: float | None = None
    vehicle: str = "f1tenth"
    kmpc_model: str | None = None
    baseline: str | None = "lmpc"
    study_options: Mapping[str, Any] = field(default_factory=dict)

    #: TrackStudy fields set by this configuration itself.
    _OWN = ("track", "scale", "vehicle", "controllers", "seed", "kmpc_model")

    def __post_init__(self) -> None:
        raw = [self.tracks] if isinstance(self.tracks, (str, Path)) else self.tracks
        if not isinstance(raw, Iterable):
            raise ParameterError(f"TracksStudyConfig.tracks must be a sequence of tracks, got {raw!r}")
        tracks = _str_tuple("TracksStudyConfig.tracks", [str(t) for t in raw])
        for t in tracks:
            _check_track(t)
        object.__setattr__(self, "tracks", tracks)
        controllers = _str_tuple("TracksStudyConfig.controllers", self.controllers)
        from rkmpc.control.factory import CONTROLLERS

        unknown = [c for c in controllers if c not in CONTROLLERS]
        if unknown:
            raise ParameterError(
                f"TracksStudyConfig.controllers: unknown {unknown}; known: {sorted(CONTROLLERS)}"
            )
        object.__setattr__(self, "controllers", controllers)
        object.__setattr__(self, "seeds", _int_tuple("TracksStudyConfig.seeds", self.seeds, minimum=0))
        _check_common(self)
        if self.baseline is not None and self.baseline not in controllers:
            raise ParameterError(
                f"TracksStudyConfig.baseline {self.baseline!r} is not among the controllers "
                f"{list(controllers)}; add it or set baseline=None"
            )
        if self.kmpc_model is not None and not Path(self.kmpc_model).is_file():
            raise ParameterError(f"TracksStudyConfig.kmpc_model: no file {self.kmpc_model}")
        if not isinstance(self.study_options, Mapping):
            raise ParameterError("TracksStudyConfig.study_options must be a mapping of TrackStudy fields")
        allowed = {f.name for f in dataclasses.fields(TrackStudy)} - set(self._OWN)
        bad = sorted(set(self.study_options) - allowed)
        if bad:
            raise ParameterError(
                f"TracksStudyConfig.study_options: {bad} are not TrackStudy fields it may set; "
                f"allowed: {sorted(allowed)}"
            )
        object.__setattr__(self, "study_options", dict(self.study_options))


def _track_job(study: dict[str, Any]) -> dict[str, Any]:
    """Worker side of :func:`study_tracks`: one TrackStudy."""
    return evaluate_track(TrackStudy(**study))


def aggregate_tracks(
    jobs: Sequence[Mapping[str, Any]],
    controllers: Sequence[str],
    baseline: str | None = "lmpc",
) -> dict[str, Any]:
    """Per-controller summary and flat per-track rows of a tracks study.

    Parameters
    ----------
    jobs : sequence of mapping
        One per (track, seed): ``track``, ``seed``, ``ok`` (False when the job
        failed), ``error`` and ``controllers`` (metrics per controller name, as
        :func:`rkmpc.experiments.learned.evaluate_track` returns them).
    controllers : sequence of str
        Controllers to summarise, in table order.
    baseline : str or None
        Controller the changes are against.

    Returns
    -------
    dict
        ``summary``: per controller, ``jobs`` (jobs in all), ``runs`` (laps
        driven), ``completed`` (laps completed), ``failed_jobs`` (jobs that
        raised: no lap, counted as not completed), ``missing`` (jobs that
        succeeded without driving it, e.g. ``kmpc`` without a model),
        ``metrics`` (statistics of each metric over the completed laps;
        ``progress`` over every lap driven) and ``change_pct`` (statistics of
        the change in % against the baseline over the (track, seed) pairs
        where both laps are complete and the baseline value is not 0).
        ``rows``: one per (track, seed, controller), in job then controller
        order, with ``ok`` (the job's), ``error``, ``status`` (``"ran"``,
        ``"failed"``: the job raised, ``"not driven"``), ``completed``, the
        metrics and ``change_pct``.
    """
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    for name in controllers:
        per_metric: dict[str, list[float | None]] = {m: [] for m in TRACK_METRICS}
        per_change: dict[str, list[float | None]] = {m: [] for m in CHANGE_METRICS}
        count = {"jobs": 0, "runs": 0, "completed": 0, "failed_jobs": 0, "missing": 0}
        for j, job in enumerate(jobs):
            count["jobs"] += 1
            row: dict[str, Any] = {
                "_job": j,
                "track": job["track"],
                "seed": job["seed"],
                "controller": name,
                "ok": bool(job["ok"]),
                "error": job.get("error"),
                "status": "failed",
                "completed": False,
            }
            if not job["ok"]:
                count["failed_jobs"] += 1
                rows.append(row)
                continue
            m = job.get("controllers", {}).get(name)
            if m is None:
                count["missing"] += 1
                row["status"] = "not driven"
                rows.append(row)
                continue
            count["runs"] += 1
            row["status"] = "ran"
            done = bool(m.get("completed", False))
            count["completed"] += int(done)
            row["completed"] = done
            row.update({k: m.get(k) for k in TRACK_METRICS})
            per_metric["progress"].append(m.get("progress"))
            if done:
                for k in TRACK_METRICS:
                    if k != "progress":
                        per_metric[k].append(m.get(k))
            base = job["controllers"].get(baseline) if baseline is not None else None
            changes: dict[str, float | None] = {}
            if base is not None:
                both = done and bool(base.get("completed", False))
                for k in CHANGE_METRICS:
                    changes[k] = change_pct(m.get(k), base.get(k)) if both else None
                    per_change[k].append(changes[k])
            row["change_pct"] = changes
            rows.append(row)
        summary[name] = {
            **count,
            "metrics": {k: stats(v) for k, v in per_metric.items()},
            "change_pct": {k: stats(v) for k, v in per_change.items()} if baseline is not None else {},
        }
    # Rows in job order (track, seed), then controller order.
    order = {name: i for i, name in enumerate(controllers)}
    rows.sort(key=lambda row: (row.pop("_job"), order[row["controller"]]))
    return {"summary": summary, "rows": rows}


def study_tracks(
    config: TracksStudyConfig,
    *,
    n_jobs: int = 1,
    backend: str = "loky",
    address: str | None = None,
    progress: Callable[[JobOutcome, int, int], None] | None = None,
) -> dict[str, Any]:
    """Evaluate the controllers on every track and seed, in parallel, and summarise.

    Each (track, seed) is one job calling
    :func:`rkmpc.experiments.learned.evaluate_track` with
    ``TrackStudy(track, scale, vehicle, controllers, seed, kmpc_model,
    **study_options)``. A job that raises is recorded (its message in the
    result) and the others go on.

    Parameters
    ----------
    config : TracksStudyConfig
        Tracks, controllers, seeds and the TrackStudy settings.
    n_jobs, backend, address
        Where the jobs run: :func:`rkmpc.experiments.parallel.run_jobs`.
    progress : callable, optional
        ``progress(outcome, done, total)`` as each job finishes
        (``outcome.name`` is ``"<track> seed <seed>"``).

    Returns
    -------
    dict
        JSON-ready: ``study`` (``"tracks"``), ``config``, ``tracks``,
        ``seeds``, ``controllers``, ``baseline``, ``parallel``, ``versions``,
        ``wall_s``, ``summary`` and ``rows`` (:func:`aggregate_tracks`), and
        ``jobs``: per (track, seed) the job's ``ok``, ``error``,
        ``seconds`` and the full result of ``evaluate_track`` (``controllers``,
        ``training``, ``config``).
    """
    if not isinstance(config, TracksStudyConfig):
        raise ParameterError("study_tracks: config must be a TracksStudyConfig")
    _check_parallel(n_jobs, backend)
    jobs = []
    keys = []
    for spec in config.tracks:
        for seed in config.seeds:
            kwargs = {
                "track": spec,
                "scale": config.scale,
                "vehicle": config.vehicle,
                "controllers": tuple(config.controllers),
                "seed": seed,
                "kmpc_model": config.kmpc_model,
                **config.study_options,
            }
            jobs.append(Job(f"{spec} seed {seed}", _track_job, (kwargs,)))
            keys.append((spec, seed))
    t0 = time.perf_counter()
    outcomes = run_jobs(
        jobs, n_jobs=n_jobs, backend=backend, address=address, on_error="record", progress=progress
    )
    wall = time.perf_counter() - t0
    records = []
    for (spec, seed), out in zip(keys, outcomes, strict=True):
        res = out.value if out.ok else {}
        records.append(
            {
                "track": res.get("track", _track_label(spec)),
                "spec": spec,
                "seed": seed,
                "ok": out.ok,
                "error": out.error,
                "traceback": out.traceback,
                "seconds": out.seconds,
                "controllers": res.get("controllers", {}),
                "training": res.get("training"),
                "config": res.get("config"),
            }
        )
    agg = aggregate_tracks(records, config.controllers, config.baseline)
    result = {
        "study": "tracks",
        "config": asdict(config),
        "tracks": list(config.tracks),
        "seeds": list(config.seeds),
        "controllers": list(config.controllers),
        "baseline": config.baseline,
        "parallel": {"n_jobs": n_jobs, "backend": backend, "address": address},
        "versions": study_versions(),
        "wall_s": wall,
        "summary": agg["summary"],
        "rows": agg["rows"],
        "jobs": records,
    }
    out_json = to_json_ready(result)
    assert isinstance(out_json, dict)
    return out_json


#: Columns of the tracks tables: metric, header, number format.
_TRACK_COLUMNS = (
    ("lateral_error_mean_m", "lat (m)", ".4f"),
    ("heading_error_mean_rad", "head (rad)", ".4f"),
    ("steer_rate_mean_rad_s", "rate (rad/s)", ".4f"),
)


def tracks_markdown(result: Mapping[str, Any]) -> str:
    """Markdown tables of a :func:`study_tracks` result: summary first, then one row per run.

    Summary cells are ``mean ± std [min, max]`` over completed laps; changes
    are against the baseline on the same track and seed.
    """
    baseline = result.get("baseline")
    summary = result["summary"]
    head = ["controller", "completed", "failed jobs"]
    for _, label, _ in _TRACK_COLUMNS:
        head.append(label)
        if baseline:
            head.append(f"{label.split(' ')[0]} vs {baseline}")
    head += ["solve mean (ms)", "solve p99 (ms)", "solve max (ms)"]
    lines = [
        f"Tracks: {len(result['tracks'])}, seeds: {', '.join(str(s) for s in result['seeds'])}.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for name in result["controllers"]:
        s = summary[name]
        cells = [name, f"{s['completed']}/{s['jobs']}", str(s["failed_jobs"])]
        for key, _, spec in _TRACK_COLUMNS:
            cells.append(_fmt_stats(s["metrics"][key], spec))
            if baseline:
                cells.append(_fmt_stats(s["change_pct"].get(key, {}), ".1f", pct=True))
        for key in ("solve_ms_mean", "solve_ms_p99", "solve_ms_max"):
            cells.append(_fmt_stats(s["metrics"][key], ".2f"))
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "| track | seed | controller | done | lat (m) | head (rad) | rate (rad/s) |"
        + (f" vs {baseline} lat / head / rate |" if baseline else "")
        + " t mean / p99 / max (ms) |",
    ]
    lines.append("|" + "---|" * (8 + (1 if baseline else 0)))
    for row in result["rows"]:
        if row.get("status", "ran") != "ran":
            error = str(row.get("error") or "").splitlines()
            done = "FAILED: " + error[0][:80].replace("|", "/") if error else str(row.get("status"))
            cells = [row["track"], str(row["seed"]), row["controller"], done] + ["-"] * (
                4 + (1 if baseline else 0)
            )
        else:
            done = "yes" if row["completed"] else "NO " + format(row.get("progress") or 0.0, ".0%")
            cells = [row["track"], str(row["seed"]), row["controller"], done]
            cells += [_fmt(row.get(k), spec) for k, _, spec in _TRACK_COLUMNS]
            if baseline:
                ch = row.get("change_pct", {})
                cells.append(
                    " / ".join("-" if ch.get(k) is None else f"{ch[k]:+.0f}%" for k, _, _ in _TRACK_COLUMNS)
                )
            cells.append(
                " / ".join(_fmt(row.get(k), ".2f") for k in ("solve_ms_mean", "solve_ms_p99", "solve_ms_max"))
            )
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------
# data volume


def _model_params() -> set[str]:
    from rkmpc.learning.koopman import KoopmanModel

    return {p for p in inspect.signature(KoopmanModel.__init__).parameters if p != "self"}


@dataclass(frozen=True)
class DataStudyConfig:
    """Settings of :func:`study_data`.

    Parameters
    ----------
    track : str
        Built-in track name or centre-line CSV path the laps are driven on.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    sizes : sequence of int
        Targets for the number of training samples: local-frame transitions
        after augmentation (``TrainReport.augmented_count``, the paper's
        ``M = N x N_p``). Each is met to within ``n_points / 2``.
    seeds : sequence of int
        Seeds (>= 0) of the data, the augmentation, the training and the lap.
    controllers : sequence of str
        Any of ``"rkmpc"`` (trained as ``residual`` on LMPC laps of the track)
        and ``"kmpc"`` (trained as ``koopman`` on random excitation of the car).
    n_points : int
        ``N_p``, transitions per augmentation window.
    rkmpc_max_ratio : float
        Largest conversion ratio for RKMPC: LMPC laps are added until the
        target can be met at a ratio at most this (then the ratio is set to
        meet it). 0.3 is the ratio of the main results (two laps, about
        11,000 samples on ``builtin``).
    kmpc_max_ratio : float
        Same for KMPC's random-excitation samples (0.05 as in the main
        results: 50,000 raw samples give about 72,000).
    min_laps, max_laps : int
        Range of the LMPC laps collected for RKMPC.
    model_options : mapping
        Overrides of :func:`rkmpc.learning.pipeline.default_model_options`
        (``KoopmanModel`` parameters such as ``epochs`` or ``max_seconds``;
        not ``seed``) for both controllers.
    """

    track: str = "builtin"
    scale: float | None = None
    vehicle: str = "f1tenth"
    sizes: Sequence[int] = DEFAULT_SIZES
    seeds: Sequence[int] = (0, 1, 2)
    controllers: Sequence[str] = ("rkmpc", "kmpc")
    n_points: int = 35
    rkmpc_max_ratio: float = 0.3
    kmpc_max_ratio: float = 0.05
    min_laps: int = 1
    max_laps: int = 40
    model_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _check_track(str(self.track))
        object.__setattr__(self, "track", str(self.track))
        _check_common(self)
        object.__setattr__(self, "sizes", _int_tuple("DataStudyConfig.sizes", self.sizes, minimum=1))
        object.__setattr__(self, "seeds", _int_tuple("DataStudyConfig.seeds", self.seeds, minimum=0))
        controllers = _str_tuple("DataStudyConfig.controllers", self.controllers)
        bad = [c for c in controllers if c not in DATA_CONTROLLERS]
        if bad:
            raise ParameterError(f"DataStudyConfig.controllers: {bad}; allowed: {sorted(DATA_CONTROLLERS)}")
        object.__setattr__(self, "controllers", controllers)
        if not _is_int(self.n_points) or self.n_points < 1:
            raise ParameterError(f"DataStudyConfig.n_points must be an integer >= 1, got {self.n_points!r}")
        for name in ("rkmpc_max_ratio", "kmpc_max_ratio"):
            v = getattr(self, name)
            if not _positive_real(v, 1.0):
                raise ParameterError(f"DataStudyConfig.{name} must be in (0, 1], got {v!r}")
        if not (_is_int(self.min_laps) and _is_int(self.max_laps) and 1 <= self.min_laps <= self.max_laps):
            raise ParameterError(
                f"DataStudyConfig: need integers 1 <= min_laps <= max_laps, got {self.min_laps!r}, "
                f"{self.max_laps!r}"
            )
        if not isinstance(self.model_options, Mapping):
            raise ParameterError("DataStudyConfig.model_options must be a mapping")
        allowed = _model_params() - {"seed"}
        bad = sorted(set(self.model_options) - allowed)
        if bad:
            raise ParameterError(
                f"DataStudyConfig.model_options: {bad} not allowed (seed comes from seeds); "
                f"allowed: {sorted(allowed)}"
            )
        object.__setattr__(self, "model_options", dict(self.model_options))
        for size in self.sizes:
            if size < self.n_points:
                raise ParameterError(
                    f"DataStudyConfig.sizes: {size} is below one window of n_points = {self.n_points}"
                )


def _windows_wanted(target: int, n_points: int) -> int:
    """Windows whose transitions come closest to ``target``."""
    return max(1, round(target / n_points))


def _lmpc_data(scenario: Any, windows: int, cfg: DataStudyConfig, seed: int) -> tuple[Any, int, int]:
    """LMPC laps holding at least ``windows / max_ratio`` window origins -> (data, laps, origins)."""
    from rkmpc.learning.augmentation import valid_origins
    from rkmpc.learning.collect import collect

    steps_per_lap = max(1.0, scenario.reference.lap_time / scenario.dt)
    need = windows / cfg.rkmpc_max_ratio
    laps = max(cfg.min_laps, math.ceil((need + cfg.n_points - 1) / steps_per_lap))
    laps = min(laps, cfg.max_laps)
    while True:
        data = collect(scenario, controller="lmpc", laps=laps, seed=seed)
        k = int(valid_origins(data, cfg.n_points).size)
        if k >= need or laps >= cfg.max_laps or not data.metadata.get("completed", True):
            return data, laps, k
        laps += 1


def _excitation_data(scenario: Any, windows: int, cfg: DataStudyConfig, seed: int) -> tuple[Any, int, int]:
    """Random excitation with at least ``windows / max_ratio`` origins -> (data, samples, origins)."""
    from rkmpc.learning.augmentation import valid_origins
    from rkmpc.learning.collect import collect_excitation

    need = windows / cfg.kmpc_max_ratio
    n = math.ceil(need * 1.25) + cfg.n_points
    for _ in range(8):
        data = collect_excitation(scenario, n_samples=n, seed=seed)
        k = int(valid_origins(data, cfg.n_points).size)
        if k >= need:
            return data, n, k
        n = math.ceil(n * need / max(k, 1) * 1.05) + cfg.n_points
    return data, n, k


def _data_job(cfg: DataStudyConfig, controller: str, size: int, seed: int) -> dict[str, Any]:
    """Worker side of :func:`study_data`: data, training and one lap for one (controller, size, seed)."""
    from rkmpc.learning.augmentation import AugmentConfig
    from rkmpc.learning.pipeline import TrainConfig, default_model_options, train_model
    from rkmpc.scenario import load_scenario

    t0 = time.perf_counter()
    scenario = load_scenario(cfg.track, scale=cfg.scale, vehicle=cfg.vehicle)
    windows = _windows_wanted(size, cfg.n_points)
    record: dict[str, Any] = {"controller": controller, "size": size, "seed": seed}
    if controller == "rkmpc":
        data, laps, origins = _lmpc_data(scenario, windows, cfg, seed)
        record["source"] = {
            "kind": "lmpc_laps",
            "laps": laps,
            "outcome": data.metadata.get("outcome"),
            "completed": data.metadata.get("completed"),
        }
    else:
        data, n_samples, origins = _excitation_data(scenario, windows, cfg, seed)
        record["source"] = {"kind": "excitation", "n_samples": n_samples}
    t_data = time.perf_counter() - t0
    ratio = min(1.0, windows / origins) if origins else 1.0
    kind = DATA_CONTROLLERS[controller]
    model_options = {**default_model_options(kind, seed=seed), **cfg.model_options}
    train_cfg = TrainConfig(
        kind=kind, augment=AugmentConfig(ratio=ratio, n_points=cfg.n_points, seed=seed), model=model_options
    )
    t1 = time.perf_counter()
    model, report = train_model(data, scenario.vehicle.wheelbase, train_cfg)
    t_train = time.perf_counter() - t1
    t2 = time.perf_counter()
    _, metrics = run_controller(scenario, RunSpec(controller, seed=seed), controller_options={"model": model})
    record.update(
        {
            "raw_count": report.raw_count,
            "augmented_count": report.augmented_count,
            "valid_origins": origins,
            "windows": report.train_windows + report.holdout_windows,
            "ratio": ratio,
            "target_met": abs(report.augmented_count - size) <= cfg.n_points / 2 + 1e-9,
            "model_options": model_options,
            "train_report": asdict(report),
            "data_s": t_data,
            "train_s": t_train,
            "fit_s": report.fit_time_s,
            "lap_s": time.perf_counter() - t2,
            "metrics": metrics,
        }
    )
    return record


def aggregate_data(jobs: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (controller, size) summary of data-study jobs.

    Parameters
    ----------
    jobs : sequence of mapping
        ``controller``, ``size``, ``seed``, ``ok`` and, for jobs that ran,
        ``metrics`` (lap metrics), ``raw_count``, ``augmented_count``,
        ``train_s``.

    Returns
    -------
    list of dict
        Sorted by controller (first seen first) and size: ``controller``,
        ``size``, ``jobs``, ``failed_jobs``, ``completed``,
        ``completion_rate`` (completed laps / jobs: a failed job counts as a lap
        not completed), ``lateral_error_mean_m`` and
        ``lateral_error_max_m`` (statistics over completed laps only: a lap
        cut short is not comparable), ``progress`` (over the jobs that drove),
        ``augmented_count``, ``raw_count`` and ``train_s`` (over the jobs that ran).
    """
    groups: dict[tuple[str, int], list[Mapping[str, Any]]] = {}
    for job in jobs:
        groups.setdefault((job["controller"], int(job["size"])), []).append(job)
    order = list(dict.fromkeys(job["controller"] for job in jobs))
    out = []
    for controller, size in sorted(groups, key=lambda k: (order.index(k[0]), k[1])):
        group = groups[(controller, size)]
        ran = [j for j in group if j["ok"]]
        done = [j for j in ran if j["metrics"].get("completed")]
        out.append(
            {
                "controller": controller,
                "size": size,
                "seeds": [j["seed"] for j in group],
                "jobs": len(group),
                "failed_jobs": len(group) - len(ran),
                "completed": len(done),
                "completion_rate": len(done) / len(group),
                "lateral_error_mean_m": stats(j["metrics"].get("lateral_error_mean_m") for j in done),
                "lateral_error_max_m": stats(j["metrics"].get("lateral_error_max_m") for j in done),
                "heading_error_mean_rad": stats(j["metrics"].get("heading_error_mean_rad") for j in done),
                "progress": stats(j["metrics"].get("progress") for j in ran),
                "augmented_count": stats(j.get("augmented_count") for j in ran),
                "raw_count": stats(j.get("raw_count") for j in ran),
                "train_s": stats(j.get("train_s") for j in ran),
            }
        )
    return out


def study_data(
    config: DataStudyConfig | None = None,
    *,
    n_jobs: int = 1,
    backend: str = "loky",
    address: str | None = None,
    progress: Callable[[JobOutcome, int, int], None] | None = None,
) -> dict[str, Any]:
    """RKMPC and KMPC as the number of training samples grows (the paper's data-volume figure).

    One job per (controller, size, seed):

    * ``rkmpc``: ``L`` LMPC laps of the track (:func:`rkmpc.learning.collect.collect`),
      ``L`` the fewest (at least ``min_laps``) whose window origins reach
      ``round(size / n_points) / rkmpc_max_ratio``; trained as ``residual``.
    * ``kmpc``: random excitation of the car
      (:func:`rkmpc.learning.collect.collect_excitation`) sized the same way
      with ``kmpc_max_ratio``; trained as ``koopman``.

    The conversion ratio is then set so that the augmentation draws
    ``round(size / n_points)`` windows: ``augmented_count`` is within
    ``n_points / 2`` of ``size`` (``target_met`` records it). The model is
    trained with :func:`rkmpc.learning.pipeline.default_model_options` (100
    epochs) updated by ``model_options``, and the controller drives one lap.

    Parameters
    ----------
    config : DataStudyConfig, optional
        Track, sizes, seeds, controllers, augmentation and model settings.
    n_jobs, backend, address
        Where the jobs run: :func:`rkmpc.experiments.parallel.run_jobs`.
    progress : callable, optional
        ``progress(outcome, done, total)`` as each job finishes
        (``outcome.name`` is ``"<controller> <size> seed <seed>"``).

    Returns
    -------
    dict
        JSON-ready: ``study`` (``"data"``), ``config``, ``track``, ``sizes``,
        ``seeds``, ``controllers``, ``parallel``, ``versions``, ``wall_s``,
        ``summary`` (:func:`aggregate_data`) and ``jobs`` (per job: ``ok``,
        ``error``, ``seconds``, raw and augmented counts, ``ratio``, the data
        source (laps or excitation samples), training times and report, and
        the lap ``metrics``).
    """
    cfg = config if config is not None else DataStudyConfig()
    if not isinstance(cfg, DataStudyConfig):
        raise ParameterError("study_data: config must be a DataStudyConfig")
    _check_parallel(n_jobs, backend)
    keys = [(c, size, seed) for c in cfg.controllers for size in cfg.sizes for seed in cfg.seeds]
    jobs = [Job(f"{c} {size} seed {seed}", _data_job, (cfg, c, size, seed)) for c, size, seed in keys]
    t0 = time.perf_counter()
    outcomes = run_jobs(
        jobs, n_jobs=n_jobs, backend=backend, address=address, on_error="record", progress=progress
    )
    wall = time.perf_counter() - t0
    baseline = _lmpc_baseline(cfg)
    records = []
    for (c, size, seed), out in zip(keys, outcomes, strict=True):
        base = {"controller": c, "size": size, "seed": seed, "metrics": {}}
        rec = {**base, **(out.value if out.ok else {})}
        rec.update({"ok": out.ok, "error": out.error, "traceback": out.traceback, "seconds": out.seconds})
        records.append(rec)
    result = {
        "study": "data",
        "config": asdict(cfg),
        "track": cfg.track,
        "sizes": list(cfg.sizes),
        "seeds": list(cfg.seeds),
        "controllers": list(cfg.controllers),
        "parallel": {"n_jobs": n_jobs, "backend": backend, "address": address},
        "versions": study_versions(),
        "wall_s": wall,
        "baseline": baseline,
        "summary": aggregate_data(records),
        "jobs": records,
    }
    out_json = to_json_ready(result)
    assert isinstance(out_json, dict)
    return out_json


def _lmpc_baseline(cfg: DataStudyConfig) -> dict[str, Any]:
    """One lap of the LMPC on the study's track: the level the learned controllers should beat."""
    from rkmpc.scenario import load_scenario

    scenario = load_scenario(cfg.track, scale=cfg.scale, vehicle=cfg.vehicle)
    _, metrics = run_controller(scenario, RunSpec("lmpc"))
    return {"controller": "lmpc", "metrics": metrics}


def data_markdown(result: Mapping[str, Any]) -> str:
    """Markdown table of a :func:`study_data` result, one row per (controller, size).

    Lateral errors are ``mean ± std [min, max]`` over the seeds whose lap
    was completed.
    """
    head = [
        "controller",
        "target samples",
        "augmented",
        "raw",
        "completed",
        "lat mean (m)",
        "lat max (m)",
        "progress",
        "train (s)",
    ]
    lines = [
        f"Track: {result['track']}, seeds: {', '.join(str(s) for s in result['seeds'])}. "
        "Samples are local-frame transitions after augmentation (M = N x N_p); raw: transitions recorded.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    base = result.get("baseline")
    if base:
        lines[0] += (
            f" LMPC on the same track: lateral error {_fmt(base['metrics']['lateral_error_mean_m'])} m"
            f" (max {_fmt(base['metrics']['lateral_error_max_m'], '.3f')} m), needs no training data."
        )
    for s in result["summary"]:
        cells = [
            s["controller"],
            str(s["size"]),
            _fmt(s["augmented_count"]["mean"], ".0f"),
            _fmt(s["raw_count"]["mean"], ".0f"),
            f"{s['completed']}/{s['jobs']}" + (f" ({s['failed_jobs']} failed)" if s["failed_jobs"] else ""),
            _fmt_stats(s["lateral_error_mean_m"]),
            _fmt_stats(s["lateral_error_max_m"]),
            _fmt(s["progress"]["mean"], ".0%"),
            _fmt(s["train_s"]["mean"], ".1f"),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    failed = [j for j in result["jobs"] if not j["ok"]]
    if failed:
        lines += ["", "Failed jobs:", ""]
        for j in failed:
            msg = str(j.get("error") or "").splitlines()[0][:120] if j.get("error") else ""
            lines.append(f"- {j['controller']} {j['size']} seed {j['seed']}: {msg}")
    return "\n".join(lines) + "\n"
