"""How fast can each controller go: :class:`PaceStudy` (issue 14, item 3).

For each controller on each track, the pace (lateral-acceleration limit and top speed together,
braking and traction scaled with them) is raised step by step up a ladder until the controller no
longer drives a clean lap (:mod:`.pace_rules`); learned controllers are trained at every pace on
data recorded at that pace (:mod:`.pace_job`). One parallel job per (track, controller); a job
that raises is recorded and the others go on. The result is each controller's fastest clean lap
per track, the pace and the tracking errors there, and its lap-time change against the LMPC and
the dynamic NMPC on the same track.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from rkmpc.analysis.statistics import stats
from rkmpc.analysis.study_plots import PaceSeries
from rkmpc.analysis.tables import fmt, fmt_stats, markdown
from rkmpc.experiments.parallel import Job, JobOutcome
from rkmpc.experiments.studies.common import json_object, track_key, track_label
from rkmpc.experiments.studies.pace_job import PaceStep, PaceStudyConfig, job_name, pace_job
from rkmpc.experiments.studies.pace_rules import MAX_FALLBACK_SHARE, pace_label
from rkmpc.experiments.study import Say, StudyRun

__all__ = ["PACE_BASELINES", "PaceRun", "PaceStudy", "PaceStudyResult"]

#: Controllers every other one's best lap time is compared with, where they are in the study.
PACE_BASELINES = ("lmpc", "nmpc-dynamic")


@dataclass(frozen=True)
class PaceRun:
    """One (track, controller) job: its steps up the ladder, or the error that stopped it."""

    spec: str
    controller: str
    ok: bool
    error: str | None
    traceback: str | None
    seconds: float
    steps: list[PaceStep]

    @property
    def track(self) -> str:
        return track_label(self.spec)

    def best(self) -> PaceStep | None:
        """The clean step with the shortest lap (the fastest clean lap), or None."""
        clean = [
            s for s in self.steps if s.clean and s.metrics is not None and s.metrics.lap_time_s is not None
        ]
        return min(clean, key=lambda s: (s.metrics.lap_time_s, s.index)) if clean else None  # type: ignore[union-attr]

    def stopped(self) -> PaceStep | None:
        """The first unclean step (where the climb stopped), or None when the whole ladder was clean."""
        return next((s for s in self.steps if not s.clean), None)

    def to_json(self) -> dict[str, Any]:
        best = self.best()
        return {
            "track": self.track,
            "spec": self.spec,
            "controller": self.controller,
            "ok": self.ok,
            "error": self.error,
            "traceback": self.traceback,
            "seconds": self.seconds,
            "best_index": None if best is None else best.index,
            "steps": [s.to_json() for s in self.steps],
        }


def _lap(step: PaceStep | None) -> float | None:
    return None if step is None or step.metrics is None else step.metrics.lap_time_s


@dataclass(frozen=True)
class PaceStudyResult:
    """What :class:`PaceStudy` found: every (track, controller) climb."""

    config: PaceStudyConfig
    run: StudyRun
    runs: list[PaceRun]

    def climb(self, track: str, controller: str) -> PaceRun | None:
        return next((r for r in self.runs if r.track == track and r.controller == controller), None)

    def tracks(self) -> list[str]:
        return list(dict.fromkeys(r.track for r in self.runs))

    def change_pct(self, run: PaceRun, baseline: str) -> float | None:
        """Best-lap-time change of ``run`` against ``baseline`` on the same track (%; negative: faster)."""
        other = self.climb(run.track, baseline)
        mine, theirs = _lap(run.best()), _lap(None if other is None else other.best())
        if mine is None or theirs is None or other is run:
            return None
        return 100.0 * (mine - theirs) / theirs

    def baselines(self) -> list[str]:
        return [b for b in PACE_BASELINES if b in self.config.controllers]

    def series(self) -> list[PaceSeries]:
        """One plot series per (controller, track) with at least one step."""
        out = []
        for r in self.runs:
            if not r.steps:
                continue
            best = r.best()
            out.append(
                PaceSeries(
                    controller=r.controller,
                    track=r.track,
                    paces=[s.pace for s in r.steps],
                    lap_time=[_lap(s) if s.clean else None for s in r.steps],
                    lateral=[
                        s.metrics.lateral_error_mean_m if s.clean and s.metrics else None for s in r.steps
                    ],
                    reference_lap_time=r.steps[0].reference_lap_time_s,
                    best_index=None if best is None else r.steps.index(best),
                )
            )
        return out

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "pace",
            "config": self.config.to_json(),
            "ladder": [list(p) for p in self.config.ladder],
            "max_fallback_share": MAX_FALLBACK_SHARE,
            "seed": self.config.seed,
            **self.run.to_json(),
            "best": [self._best_row(r) for r in self.runs],
            "runs": [r.to_json() for r in self.runs],
        }
        return json_object(out)

    def _best_row(self, run: PaceRun) -> dict[str, Any]:
        best, stop = run.best(), run.stopped()
        return {
            "track": run.track,
            "controller": run.controller,
            "lap_time_s": _lap(best),
            "pace": None if best is None else list(best.pace),
            "metrics": None if best is None or best.metrics is None else best.metrics.to_json(),
            "change_pct": {b: self.change_pct(run, b) for b in self.baselines()},
            "stopped_at": None if stop is None else list(stop.pace),
            "stopped_because": None if stop is None else stop.reason,
            "error": run.error,
        }

    def to_markdown(self) -> str:
        return pace_markdown(self)

    def figure(self) -> Any:
        """Lap time and lateral error up the ladder, per controller and track."""
        from rkmpc.analysis.study_plots import plot_pace_study

        title = f"pace study, seed {self.config.seed}: clean laps up the pace ladder"
        return plot_pace_study(self.series(), title)


def pace_markdown(result: PaceStudyResult) -> str:
    """The summary per controller, the best clean lap per (track, controller), then every step."""
    cfg = result.config
    bases = result.baselines()
    intro = (
        f"Pace study, seed {cfg.seed}, {len(result.tracks())} tracks. Ladder (lateral limit m/s^2 / "
        f"top speed m/s): {', '.join(pace_label(p) for p in cfg.ladder)}. A lap is clean when it is "
        f"completed, no step is inadmissible and at most {MAX_FALLBACK_SHARE:.0%} of the steps fall back; "
        "each controller stops at its first unclean pace. Changes are of the best clean lap time "
        "(negative: faster).\n\n"
    )
    head = ["controller", "tracks clean", *(f"lap vs {b}" for b in bases)]
    rows = []
    for name in cfg.controllers:
        runs = [r for r in result.runs if r.controller == name]
        cells = [name, f"{sum(r.best() is not None for r in runs)}/{len(runs)}"]
        for b in bases:
            cells.append(fmt_stats(stats(result.change_pct(r, b) for r in runs), ".1f", pct=True))
        rows.append(cells)
    text = intro + markdown(head, rows) + "\n"
    head = ["track", "controller", "best lap (s)", "pace", "lat (m)", "lat max (m)", "head (rad)"]
    head += [f"vs {b}" for b in bases] + ["stopped at"]
    rows = []
    for r in result.runs:
        best, stop = r.best(), r.stopped()
        m = None if best is None else best.metrics
        cells = [
            r.track,
            r.controller,
            fmt(_lap(best), ".2f"),
            "-" if best is None else pace_label(best.pace),
        ]
        cells += [
            fmt(m.lateral_error_mean_m if m else None, ".4f"),
            fmt(m.lateral_error_max_m if m else None, ".3f"),
            fmt(m.heading_error_mean_rad if m else None, ".4f"),
        ]
        for b in bases:
            change = result.change_pct(r, b)
            cells.append("-" if change is None else f"{change:+.1f}%")
        if not r.ok:
            cells.append("FAILED: " + str(r.error or "").splitlines()[0][:80].replace("|", "/"))
        else:
            cells.append("top of ladder" if stop is None else f"{pace_label(stop.pace)}: {stop.reason}")
        rows.append(cells)
    text += "\n" + markdown(head, rows) + "\n"
    head = ["track", "controller", "pace", "ref lap (s)", "clean", "lap (s)", "lat (m)", "fall-backs", "data"]
    rows = []
    for r in result.runs:
        for s in r.steps:
            m = s.metrics
            cells = [r.track, r.controller, pace_label(s.pace), fmt(s.reference_lap_time_s, ".2f")]
            cells.append("yes" if s.clean else f"no: {s.reason}".replace("|", "/"))
            cells += [fmt(_lap(s), ".2f"), fmt(m.lateral_error_mean_m if m else None, ".4f")]
            cells.append("-" if m is None else f"{m.fallback_count}/{m.steps}")
            cells.append(_data_cell(s))
            rows.append(cells)
    return text + "\nEvery step:\n\n" + markdown(head, rows)


def _data_cell(step: PaceStep) -> str:
    d = step.data
    if d is None:
        return "-"
    if d.recorder == "excitation":
        return f"excitation {d.samples}"
    at = "" if d.recorder_pace is None else f" (model of {pace_label(d.recorder_pace)})"
    lmpc = "" if d.lmpc_clean else " [lmpc unclean]"
    return f"{d.recorder}{at} {d.samples}{lmpc}"


@dataclass(frozen=True)
class PaceStudy:
    """Each controller up the pace ladder on every track (``rkmpc study pace``)."""

    config: PaceStudyConfig
    name: ClassVar[str] = "pace"

    def keys(self) -> list[tuple[str, str]]:
        return [(t, c) for t in self.config.tracks for c in self.config.controllers]

    def prepare(self, say: Say) -> None:
        """Nothing shared: every climb learns at every pace."""

    def jobs(self) -> list[Job]:
        return [
            Job(job_name(t, c), pace_job, (self.config, t, c), key=f"{track_key(t)} {c}")
            for t, c in self.keys()
        ]

    def journal_settings(self) -> dict[str, Any]:
        """Its settings but the tracks, controllers and cache: a journal of the same settings is reused
        by a run over more tracks or controllers (the job key is the track, a file by its absolute
        path, and the controller)."""
        settings = self.config.to_json()
        for name in ("tracks", "controllers", "cache_dir", "use_cache"):
            settings.pop(name)
        return settings

    def encode(self, value: list[PaceStep]) -> list[dict[str, Any]]:
        return [json_object(step.to_json()) for step in value]

    def decode(self, data: Any) -> list[PaceStep]:
        return [PaceStep.from_json(step) for step in data]

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> PaceStudyResult:
        runs = [
            PaceRun(
                spec=t,
                controller=c,
                ok=out.ok,
                error=out.error,
                traceback=out.traceback,
                seconds=out.seconds,
                steps=list(out.value) if out.ok else [],
            )
            for (t, c), out in zip(self.keys(), outcomes, strict=True)
        ]
        return PaceStudyResult(config=self.config, run=run, runs=runs)
