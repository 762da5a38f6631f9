"""Every controller on many tracks: :func:`study_tracks`.

The comparison of :func:`rkmpc.experiments.compare.compare` on a list of
tracks and seeds, one parallel job per (track, seed) through
:func:`rkmpc.experiments.parallel.run_jobs`, summarised per controller over
all of them (:func:`rkmpc.analysis.statistics.summarise_runs`): mean and
spread of every lap metric and of its change in % against a baseline
controller (``lmpc``) on the same track and seed. A job that raises is
recorded (its message in the result) and the others go on.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from rkmpc.analysis.statistics import ControllerSummary, RunGroup, RunRow, summarise_runs
from rkmpc.analysis.tables import fmt, fmt_stats, markdown
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.compare import LEARNED_CONTROLLERS, CompareConfig, compare
from rkmpc.experiments.journal import JobJournal, canonical_json
from rkmpc.experiments.models import train_excitation_model
from rkmpc.experiments.parallel import Job, JobOutcome, run_jobs
from rkmpc.experiments.results import TrackResult
from rkmpc.experiments.studies.common import (
    check_parallel,
    check_scale_vehicle,
    controller_names,
    int_tuple,
    json_object,
    study_versions,
    track_label,
    track_specs,
)
from rkmpc.learning.recipes import recipe_for

__all__ = [
    "TrackJob",
    "TracksStudyConfig",
    "TracksStudyResult",
    "run_track_jobs",
    "study_tracks",
    "summary_table",
    "track_journal_settings",
    "train_shared_models",
]


@dataclass(frozen=True)
class TracksStudyConfig:
    """Settings of :func:`study_tracks`.

    Parameters
    ----------
    tracks : sequence of str
        Built-in track names or centre-line CSV paths (see
        :func:`rkmpc.experiments.studies.common.expand_tracks`).
    controllers : sequence of str
        Controllers each job drives; a comma-separated string is accepted.
    seeds : sequence of int
        Seeds (>= 0); one job per (track, seed). The seed sets the data
        collection, training and the runs.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    kmpc_model : str or None
        Path of a trained ``koopman`` model for ``kmpc``.
    baseline : str or None
        Controller the changes in % are measured against (must be in
        ``controllers``); None for no changes.
    study_options : mapping
        Further fields of :class:`rkmpc.experiments.compare.CompareConfig`
        (any other than the ones above), passed to every job; values must be picklable.
    """

    tracks: Sequence[str]
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    seeds: Sequence[int] = (0,)
    scale: float | None = None
    vehicle: str = "f1tenth"
    kmpc_model: str | None = None
    baseline: str | None = "lmpc"
    study_options: Mapping[str, Any] = field(default_factory=dict)

    #: CompareConfig fields set by this configuration itself.
    _OWN = ("track", "scale", "vehicle", "controllers", "seed", "kmpc_model")

    def __post_init__(self) -> None:
        object.__setattr__(self, "tracks", track_specs("TracksStudyConfig.tracks", self.tracks))
        controllers = controller_names("TracksStudyConfig.controllers", self.controllers)
        object.__setattr__(self, "controllers", controllers)
        object.__setattr__(self, "seeds", int_tuple("TracksStudyConfig.seeds", self.seeds, minimum=0))
        check_scale_vehicle(self.scale, self.vehicle)
        if self.baseline is not None and self.baseline not in controllers:
            raise ParameterError(
                f"TracksStudyConfig.baseline {self.baseline!r} is not among the controllers "
                f"{list(controllers)}; add it or set baseline=None"
            )
        if self.kmpc_model is not None and not Path(self.kmpc_model).is_file():
            raise ParameterError(f"TracksStudyConfig.kmpc_model: no file {self.kmpc_model}")
        if not isinstance(self.study_options, Mapping):
            raise ParameterError("TracksStudyConfig.study_options must be a mapping of CompareConfig fields")
        allowed = {f.name for f in dataclasses.fields(CompareConfig)} - set(self._OWN)
        bad = sorted(set(self.study_options) - allowed)
        if bad:
            raise ParameterError(
                f"TracksStudyConfig.study_options: {bad} are not CompareConfig fields it may set; "
                f"allowed: {sorted(allowed)}"
            )
        object.__setattr__(self, "study_options", dict(self.study_options))

    def job_config(self, track: str, seed: int) -> CompareConfig:
        """The comparison of one (track, seed) job."""
        return CompareConfig(
            track=track,
            scale=self.scale,
            vehicle=self.vehicle,
            controllers=tuple(self.controllers),
            seed=seed,
            kmpc_model=self.kmpc_model,
            **self.study_options,
        )


@dataclass(frozen=True)
class TrackJob:
    """One (track, seed) job of the study: its outcome and, when it ran, its comparison."""

    spec: str
    seed: int
    ok: bool
    error: str | None
    traceback: str | None
    seconds: float
    result: TrackResult | None

    @property
    def track(self) -> str:
        return self.result.track if self.result is not None else track_label(self.spec)

    def group(self) -> RunGroup:
        metrics = {} if self.result is None else self.result.metrics()
        return RunGroup(track=self.track, seed=self.seed, ok=self.ok, error=self.error, metrics=metrics)

    def to_json(self) -> dict[str, Any]:
        res = self.result.to_json() if self.result is not None else {}
        return {
            "track": self.track,
            "spec": self.spec,
            "seed": self.seed,
            "ok": self.ok,
            "error": self.error,
            "traceback": self.traceback,
            "seconds": self.seconds,
            "controllers": res["controllers"] if res else {},
            "training": res["training"] if res else None,
            "config": res["config"] if res else None,
        }


@dataclass(frozen=True)
class TracksStudyResult:
    """What :func:`study_tracks` found: the summary per controller, one row per run, every job."""

    config: TracksStudyConfig
    parallel: dict[str, Any]
    versions: dict[str, str]
    wall_s: float
    summary: dict[str, ControllerSummary]
    rows: list[RunRow]
    jobs: list[TrackJob]

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "tracks",
            "config": asdict(self.config),
            "tracks": list(self.config.tracks),
            "seeds": list(self.config.seeds),
            "controllers": list(self.config.controllers),
            "baseline": self.config.baseline,
            "parallel": self.parallel,
            "versions": self.versions,
            "wall_s": self.wall_s,
            "summary": {name: s.to_json() for name, s in self.summary.items()},
            "rows": [row.to_json() for row in self.rows],
            "jobs": [job.to_json() for job in self.jobs],
        }
        return json_object(out)

    def to_markdown(self) -> str:
        """The summary table (``mean ± std [min, max]`` over completed laps), then one row per run."""
        return tracks_markdown(self)


def study_tracks(
    config: TracksStudyConfig,
    *,
    n_jobs: int = 1,
    backend: str = "loky",
    address: str | None = None,
    progress: Callable[[JobOutcome, int, int], None] | None = None,
    say: Callable[[str], None] | None = None,
    journal: JobJournal | None = None,
) -> TracksStudyResult:
    """Compare the controllers on every track and seed, in parallel, and summarise.

    Models that do not depend on the track (random-excitation recipes, KMPC) are
    trained once per seed in this process first, so that the jobs read them from
    the model cache instead of each training its own.

    Parameters
    ----------
    config : TracksStudyConfig
        Tracks, controllers, seeds and the comparison settings.
    n_jobs, backend, address
        Where the jobs run: :func:`rkmpc.experiments.parallel.run_jobs`.
    progress : callable, optional
        ``progress(outcome, done, total)`` as each job finishes
        (``outcome.name`` is ``"<track> seed <seed>"``).
    say : callable, optional
        Called with a short message before each slow stage.
    journal : JobJournal, optional
        Finished jobs kept across runs (:func:`run_track_jobs`), opened with
        :func:`track_journal_settings`.
    """
    if not isinstance(config, TracksStudyConfig):
        raise ParameterError("study_tracks: config must be a TracksStudyConfig")
    check_parallel(n_jobs, backend)
    tell = say if say is not None else (lambda _msg: None)
    train_shared_models([config.job_config(config.tracks[0], seed) for seed in config.seeds], tell)
    tell(f"{len(config.tracks)} tracks x {len(config.seeds)} seeds on {n_jobs} {backend} workers")
    named = [
        (f"{spec} seed {seed}", config.job_config(spec, seed))
        for spec in config.tracks
        for seed in config.seeds
    ]
    records, wall = run_track_jobs(
        named, n_jobs=n_jobs, backend=backend, address=address, progress=progress, journal=journal
    )
    summary, rows = summarise_runs([job.group() for job in records], config.controllers, config.baseline)
    return TracksStudyResult(
        config=config,
        parallel={"n_jobs": n_jobs, "backend": backend, "address": address},
        versions=study_versions(),
        wall_s=wall,
        summary=summary,
        rows=rows,
        jobs=records,
    )


def track_journal_settings(study: str) -> dict[str, Any]:
    """What the journal of a tracks or cars study must match: the study and the package versions.

    Everything else is in each job's key (its whole :class:`CompareConfig`).
    """
    return {"study": study, "versions": study_versions()}


def run_track_jobs(
    named: Sequence[tuple[str, CompareConfig]],
    *,
    n_jobs: int,
    backend: str,
    address: str | None,
    progress: Callable[[JobOutcome, int, int], None] | None,
    journal: JobJournal | None = None,
) -> tuple[list[TrackJob], float]:
    """Run one :func:`compare` per ``(name, config)`` in parallel; a job that raises is recorded.

    With a ``journal``, a job's key is its whole configuration (canonical JSON), so a finished
    job is reused only by a job configured exactly alike.

    Returns the jobs, in the given order, and the wall time of the whole run (s, for reports).
    """
    jobs = [Job(name, compare, (cfg,), key=canonical_json(cfg)) for name, cfg in named]
    t0 = time.perf_counter()
    outcomes = run_jobs(
        jobs,
        n_jobs=n_jobs,
        backend=backend,
        address=address,
        on_error="record",
        progress=progress,
        journal=journal,
    )
    wall = time.perf_counter() - t0
    records = [
        TrackJob(
            spec=cfg.track,
            seed=cfg.seed,
            ok=out.ok,
            error=out.error,
            traceback=out.traceback,
            seconds=out.seconds,
            result=out.value if out.ok else None,
        )
        for (_, cfg), out in zip(named, outcomes, strict=True)
    ]
    return records, wall


def train_shared_models(jobs: Sequence[CompareConfig], tell: Callable[[str], None]) -> None:
    """Train the track-independent models of ``jobs`` (one per seed and car) once, into their cache."""
    for job in jobs:
        if not job.use_cache:
            return
        seed = job.seed
        plan = job.plan()
        shared = [
            r for name in plan.controllers if (r := recipe_for(name)) is not None and r.data == "excitation"
        ]
        for recipe in shared:
            if recipe.controller in plan.model_files:
                continue
            tell(f"{recipe.controller} model, seed {seed}: {plan.excitation_samples} samples (cached)")
            train_excitation_model(
                job.scenario(),
                recipe,
                samples=plan.excitation_samples,
                seed=seed,
                cache=ModelCache(plan.cache_dir),
                epochs=plan.epochs,
            )


#: Columns of the tracks tables: metric, header, number format.
_TRACK_COLUMNS = (
    ("lateral_error_mean_m", "lat (m)", ".4f"),
    ("lateral_error_max_m", "lat max (m)", ".3f"),
    ("heading_error_mean_rad", "head (rad)", ".4f"),
    ("steer_rate_mean_rad_s", "rate (rad/s)", ".4f"),
    ("command_rate_mean_rad_s", "cmd rate (rad/s)", ".4f"),
)
_SOLVE = ("solve_ms_mean", "solve_ms_p99", "solve_ms_max")


def summary_table(summary: Mapping[str, ControllerSummary], config: TracksStudyConfig) -> str:
    """Markdown: one row per controller of ``config``, ``mean ± std [min, max]`` of each metric."""
    baseline = config.baseline
    head = ["controller", "completed", "failed jobs"]
    for _, label, _ in _TRACK_COLUMNS:
        head.append(label)
        if baseline:
            head.append(f"{label.split(' ')[0]} vs {baseline}")
    head += ["solve mean (ms)", "solve p99 (ms)", "solve max (ms)"]
    rows = []
    for name in config.controllers:
        s = summary[name]
        cells = [name, f"{s.completed}/{s.jobs}", str(s.failed_jobs)]
        for key, _, spec in _TRACK_COLUMNS:
            cells.append(fmt_stats(s.metrics[key], spec))
            if baseline:
                cells.append(fmt_stats(s.change_pct[key] if key in s.change_pct else None, ".1f", pct=True))
        cells += [fmt_stats(s.metrics[key], ".2f") for key in _SOLVE]
        rows.append(cells)
    return markdown(head, rows)


def _row_cells(row: RunRow, baseline: str | None) -> list[str]:
    cells = [row.track, str(row.seed), row.controller]
    if row.status != "ran":
        error = str(row.error or "").splitlines()
        cells.append("FAILED: " + error[0][:80].replace("|", "/") if error else row.status)
        return cells + ["-"] * (len(_TRACK_COLUMNS) + 2 + (1 if baseline else 0))
    progress = row.metrics["progress"]
    cells.append("yes" if row.completed else "NO " + format(progress or 0.0, ".0%"))
    cells += [fmt(row.metrics[k], spec) for k, _, spec in _TRACK_COLUMNS]
    if baseline:
        ch = row.change_pct or {}
        changes = [ch[k] if k in ch else None for k, _, _ in _TRACK_COLUMNS]
        cells.append(" / ".join("-" if c is None else f"{c:+.0f}%" for c in changes))
    cells.append(" / ".join(fmt(row.metrics[k], ".2f") for k in _SOLVE))
    return cells


def tracks_markdown(result: TracksStudyResult) -> str:
    """Markdown of a tracks study: the summary first, then one row per run."""
    baseline = result.config.baseline
    lines = [
        f"Tracks: {len(result.config.tracks)}, seeds: {', '.join(str(s) for s in result.config.seeds)}.",
        "",
    ]
    head = ["track", "seed", "controller", "done", *(label for _, label, _ in _TRACK_COLUMNS)]
    if baseline:
        head.append(f"vs {baseline}: " + " / ".join(label.split(" (")[0] for _, label, _ in _TRACK_COLUMNS))
    head.append("t mean / p99 / max (ms)")
    rows = [_row_cells(row, baseline) for row in result.rows]
    return "\n".join(lines) + summary_table(result.summary, result.config) + "\n" + markdown(head, rows)
