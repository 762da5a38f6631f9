"""Studies over tracks and data sizes: small parallel runs, aggregation math, JSON, plots."""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.analysis.statistics import RunGroup, summarise_runs
from rkmpc.analysis.study_plots import plot_data_study
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.core.versions import versions
from rkmpc.experiments.studies.common import expand_tracks
from rkmpc.experiments.studies.data import (
    DataJob,
    DataStudy,
    DataStudyConfig,
    DataStudyResult,
    summarise_sizes,
)
from rkmpc.experiments.studies.data_job import DataRun
from rkmpc.experiments.studies.tracks import TracksStudy, TracksStudyConfig, TracksStudyResult
from rkmpc.experiments.study import Parallel, StudyRun, run_study

#: How a study made of hand-made rows ran (nowhere).
HAND_RUN = StudyRun(parallel=Parallel(), versions=versions(), wall_s=0.0)


def _metrics(lat: float, completed: bool = True, progress: float = 1.0, **extra: float) -> dict:
    base = {
        "completed": completed,
        "progress": progress,
        "lap_time_s": 20.0 if completed else None,
        "lateral_error_mean_m": lat,
        "lateral_error_max_m": 3 * lat,
        "heading_error_mean_rad": lat / 2,
        "steer_rate_mean_rad_s": 0.1,
        "command_rate_mean_rad_s": 0.2,
        "solve_ms_mean": 0.5,
        "solve_ms_p99": 1.0,
        "solve_ms_max": 2.0,
        "fallback_count": 0,
        "steps": 100,
        "lateral_accel_max_m_s2": None,
    }
    base.update(extra)
    return base


# ---------------------------------------------------------------------------
# small parallel runs


@pytest.mark.slow
def test_study_tracks_two_builtin_tracks_in_parallel():
    seen = []
    cfg = TracksStudyConfig(tracks=("builtin", "oval"), controllers=("pp", "lmpc"), seeds=(0,))
    typed = run_study(
        TracksStudy(cfg),
        parallel=Parallel(n_jobs=2),
        progress=lambda o, done, total: seen.append((o.name, done, total)),
    )
    result = typed.to_json()
    assert sorted(s[0] for s in seen) == ["builtin seed 0", "oval seed 0"]
    assert [s[1:] for s in sorted(seen, key=lambda s: s[1])] == [(1, 2), (2, 2)]
    json.dumps(result, allow_nan=False)
    config = result["config"]
    assert config["tracks"] == ["builtin", "oval"] and config["seeds"] == [0]
    assert config["controllers"] == ["pp", "lmpc"] and config["baseline"] == "lmpc"
    assert config["car"] == load_preset("f1tenth").to_json()
    assert result["parallel"] == {"n_jobs": 2, "backend": "loky", "address": None}
    assert {"python", "numpy", "rkmpc", "torch", "joblib"} <= set(result["versions"])
    assert [j["track"] for j in result["jobs"]] == ["builtin", "oval"]
    assert all(j["ok"] for j in result["jobs"]), [j["error"] for j in result["jobs"]]
    for name in ("pp", "lmpc"):
        s = result["summary"][name]
        assert (s["jobs"], s["runs"], s["completed"], s["failed_jobs"]) == (2, 2, 2, 0)
        lat = [j["controllers"][name]["lateral_error_mean_m"] for j in result["jobs"]]
        assert s["metrics"]["lateral_error_mean_m"]["mean"] == pytest.approx(np.mean(lat))
        assert s["metrics"]["lateral_error_mean_m"]["std"] == pytest.approx(np.std(lat, ddof=1))
    lmpc_change = result["summary"]["lmpc"]["change_pct"]["lateral_error_mean_m"]
    assert lmpc_change["mean"] == 0.0 and lmpc_change["n"] == 2
    assert len(result["rows"]) == 4
    md = typed.to_markdown()
    assert md.index("| controller |") < md.index("| track | seed |")
    assert "| pp | 2/2 |" in md and "| oval | 0 | lmpc | yes |" in md


@pytest.mark.slow
def test_study_data_tiny_sizes_in_parallel():
    cfg = DataStudyConfig(sizes=(350, 1400), seeds=(0,), car=load_preset("f1tenth").with_training(epochs=1))
    typed = run_study(DataStudy(cfg), parallel=Parallel(n_jobs=2))
    result = typed.to_json()
    json.dumps(result, allow_nan=False)
    assert result["sizes"] == [350, 1400] and result["seeds"] == [0]
    assert result["config"]["car"]["training"]["epochs"] == 1
    jobs = result["jobs"]
    assert [(j["controller"], j["size"]) for j in jobs] == [
        ("rkmpc", 350),
        ("rkmpc", 1400),
        ("kmpc", 350),
        ("kmpc", 1400),
    ]
    for j in jobs:
        assert j["ok"], j["error"]
        assert abs(j["augmented_count"] - j["size"]) <= 35 / 2
        assert j["target_met"]
        training = j["model_options"]["lifting"]["training"]
        assert training["seed"] == 0 and training["epochs"] == 1
        assert 0 < j["ratio"] <= 1
        assert set(j["metrics"]) >= {"completed", "progress", "lateral_error_mean_m"}
    rk = [j for j in jobs if j["controller"] == "rkmpc"]
    assert all(j["source"]["kind"] == "lmpc_laps" and j["source"]["laps"] == 1 for j in rk)
    assert rk[0]["ratio"] <= 0.3 and rk[1]["ratio"] <= 0.3
    km = [j for j in jobs if j["controller"] == "kmpc"]
    assert all(j["source"]["kind"] == "excitation" and j["ratio"] <= 0.05 for j in km)
    assert km[1]["raw_count"] > km[0]["raw_count"]
    summary = result["summary"]
    assert [(s["controller"], s["size"], s["jobs"]) for s in summary] == [
        ("rkmpc", 350, 1),
        ("rkmpc", 1400, 1),
        ("kmpc", 350, 1),
        ("kmpc", 1400, 1),
    ]
    md = typed.to_markdown()
    assert "| rkmpc | 350 |" in md and "| kmpc | 1400 |" in md
    fig = plot_data_study(typed.series(), typed.baseline.lateral_error_mean_m, "data")
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    assert isinstance(typed.figure(), Figure)


# ---------------------------------------------------------------------------
# aggregation on hand-made rows


def test_aggregate_tracks_by_hand():
    jobs = [
        RunGroup("a", 0, True, None, {"lmpc": _metrics(0.02), "rkmpc": _metrics(0.01)}),
        RunGroup("b", 0, True, None, {"lmpc": _metrics(0.04), "rkmpc": _metrics(0.05)}),
        RunGroup("c", 0, True, None, {"lmpc": _metrics(0.03), "rkmpc": _metrics(0.5, False, progress=0.4)}),
        RunGroup("d", 0, True, None, {"lmpc": _metrics(0.03)}),
        RunGroup("e", 0, False, "InputFileError: bad CSV", {}),
    ]
    summary, run_rows = summarise_runs(jobs, ["lmpc", "rkmpc"], "lmpc")
    agg = {"summary": {k: s.to_json() for k, s in summary.items()}, "rows": [r.to_json() for r in run_rows]}
    rk = agg["summary"]["rkmpc"]
    assert (rk["jobs"], rk["runs"], rk["completed"], rk["failed_jobs"], rk["missing"]) == (5, 3, 2, 1, 1)
    lat = rk["metrics"]["lateral_error_mean_m"]  # completed laps only: 0.01, 0.05
    assert lat["n"] == 2 and lat["mean"] == pytest.approx(0.03)
    assert lat["std"] == pytest.approx(np.std([0.01, 0.05], ddof=1))
    assert (lat["min"], lat["max"]) == (0.01, 0.05)
    assert rk["metrics"]["progress"]["mean"] == pytest.approx(0.8)  # every lap driven
    ch = rk["change_pct"]["lateral_error_mean_m"]  # -50 % and +25 %; track c not compared
    assert ch["n"] == 2 and ch["mean"] == pytest.approx(-12.5)
    assert (ch["min"], ch["max"]) == (pytest.approx(-50.0), pytest.approx(25.0))
    assert rk["change_pct"]["fallback_count"]["n"] == 0  # baseline 0: no change defined
    lm = agg["summary"]["lmpc"]
    assert (lm["runs"], lm["completed"], lm["failed_jobs"]) == (4, 4, 1)
    assert lm["change_pct"]["lateral_error_mean_m"]["mean"] == 0.0
    rows = {(r["track"], r["controller"]): r for r in agg["rows"]}
    assert len(rows) == 10
    assert rows[("a", "rkmpc")]["change_pct"]["lateral_error_mean_m"] == pytest.approx(-50.0)
    assert rows[("c", "rkmpc")]["change_pct"]["lateral_error_mean_m"] is None
    assert not rows[("e", "lmpc")]["ok"] and "bad CSV" in rows[("e", "lmpc")]["error"]
    assert rows[("d", "rkmpc")]["status"] == "not driven" and rows[("d", "rkmpc")]["ok"]
    assert rows[("a", "rkmpc")]["status"] == "ran" and rows[("e", "rkmpc")]["status"] == "failed"
    assert [(r["track"], r["controller"]) for r in agg["rows"][:3]] == [
        ("a", "lmpc"),
        ("a", "rkmpc"),
        ("b", "lmpc"),
    ]
    cfg = TracksStudyConfig(tracks=("builtin",), controllers=("lmpc", "rkmpc"))
    result = TracksStudyResult(config=cfg, run=HAND_RUN, summary=summary, rows=run_rows, jobs=[])
    md = result.to_markdown()
    assert result.figure() is None  # the tables say it
    assert "| rkmpc | 2/5 | 1 |" in md
    assert "FAILED: InputFileError: bad CSV" in md and "NO 40%" in md
    assert "| d | 0 | rkmpc | not driven |" in md
    no_base, _ = summarise_runs(jobs, ["rkmpc"], None)
    assert no_base["rkmpc"].change_pct == {}


def _data_run(controller: str, size: int, seed: int, metrics: dict) -> DataRun:
    return DataRun(
        controller=controller,
        size=size,
        seed=seed,
        source={"kind": "lmpc_laps", "laps": 1, "outcome": "completed", "completed": True},
        raw_count=size // 3,
        augmented_count=size + 2 * seed,
        valid_origins=size,
        windows=size // 35,
        ratio=0.3,
        target_met=True,
        model_options={},
        train_report={},
        data_s=0.5,
        train_s=1.0,
        fit_s=1.0,
        lap_s=2.0,
        metrics=LapMetrics.from_json(metrics),
    )


def test_aggregate_data_by_hand():
    def job(controller, size, seed, lat=None, completed=True, ok=True, error=None):
        metrics = _metrics(lat, completed=completed, progress=1.0 if completed else 0.5) if ok else {}
        return DataJob(
            controller=controller,
            size=size,
            seed=seed,
            ok=ok,
            error=error,
            traceback=None,
            seconds=1.0,
            run=_data_run(controller, size, seed, metrics) if ok else None,
        )

    jobs = [
        job("rkmpc", 1000, 0, 0.02),
        job("rkmpc", 1000, 1, 0.04),
        job("rkmpc", 1000, 2, 0.9, completed=False),
        job("kmpc", 1000, 0, ok=False),
        job("kmpc", 1000, 1, 0.2),
        job("kmpc", 1000, 2, 0.3),
        job("rkmpc", 500, 0, 0.05),
    ]
    typed = summarise_sizes(jobs)
    summary = [asdict(s) for s in typed]
    keys = [(s["controller"], s["size"]) for s in summary]
    assert keys == [("rkmpc", 500), ("rkmpc", 1000), ("kmpc", 1000)]
    rk = summary[1]
    assert (rk["jobs"], rk["completed"], rk["failed_jobs"]) == (3, 2, 0)
    assert rk["completion_rate"] == pytest.approx(2 / 3)
    assert rk["lateral_error_mean_m"]["mean"] == pytest.approx(0.03)
    assert rk["progress"]["mean"] == pytest.approx((1 + 1 + 0.5) / 3)
    assert rk["augmented_count"]["mean"] == pytest.approx(1002.0)
    km = summary[2]
    assert (km["jobs"], km["completed"], km["failed_jobs"]) == (3, 2, 1)
    assert km["completion_rate"] == pytest.approx(2 / 3)  # the failed job counts as not completed
    assert km["lateral_error_mean_m"]["n"] == 2 and km["progress"]["n"] == 2
    failed = [replace(j, error="RuntimeError: boom") if not j.ok else j for j in jobs]
    cfg = DataStudyConfig(seeds=(0, 1, 2))
    baseline = LapMetrics.from_json(_metrics(0.04))
    result = DataStudyResult(config=cfg, run=HAND_RUN, baseline=baseline, summary=typed, jobs=failed)
    record = result.to_json()
    json.dumps(record, allow_nan=False)
    assert [j["ok"] for j in record["jobs"]] == [j.ok for j in jobs]
    assert record["jobs"][0]["augmented_count"] == 1000 and record["jobs"][3]["error"] == "RuntimeError: boom"
    assert DataRun.from_json(record["jobs"][0]) == jobs[0].run  # the journal's round trip
    md = result.to_markdown()
    assert "| kmpc | 1000 | 1003 | 333 | 2/3 (1 failed) |" in md
    assert "- kmpc 1000 seed 0: RuntimeError: boom" in md

    fig = plot_data_study(result.series(), None, "data")
    ax_err, ax_done = fig.axes
    assert ax_err.get_xscale() == "log" and ax_done.get_xscale() == "log"
    assert len(ax_err.containers) == 2 and len(ax_done.lines) == 2  # error bars of both controllers
    err_lines = [c.lines[0] for c in ax_err.containers]
    assert sum(isinstance(c, PolyCollection) for c in ax_err.collections) == 2  # min-max bands
    assert [t.get_text() for t in ax_done.get_legend().get_texts()] == ["RKMPC", "KMPC"]
    np.testing.assert_allclose(ax_done.lines[0].get_ydata(), [1.0, 2 / 3])
    np.testing.assert_allclose(err_lines[0].get_ydata(), [0.05, 0.03])
    np.testing.assert_allclose(err_lines[1].get_xdata(), [1003.0])


# ---------------------------------------------------------------------------
# configuration


def test_configs_validate(tmp_path):
    csv = tmp_path / "T.csv"
    csv.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n")
    assert expand_tracks(["builtin", tmp_path]) == ("builtin", str(csv))
    cfg = TracksStudyConfig(tracks=["oval"], controllers="pp,lmpc", seeds=[1, 2])
    assert cfg.controllers == ("pp", "lmpc") and cfg.seeds == (1, 2)
    assert TracksStudyConfig(tracks="oval").tracks == ("oval",)
    assert cfg.car == load_preset("f1tenth")
    bad_tracks = [
        ({"tracks": ()}, "empty"),
        ({"tracks": ("nowhere.csv",)}, "neither a built-in"),
        ({"tracks": ("oval",), "controllers": ("warp",)}, "unknown"),
        ({"tracks": ("oval",), "controllers": ("pp",)}, "baseline"),
        ({"tracks": ("oval",), "seeds": (0, 0)}, "repeat"),
        ({"tracks": ("oval",), "seeds": (-1,)}, "seeds"),
        ({"tracks": ("oval",), "scale": 0.0}, "scale"),
        ({"tracks": ("oval",), "car": "bus"}, "TracksStudyConfig.car must be a CarConfig"),
        ({"tracks": ("oval",), "fault": "ice"}, "unknown fault 'ice'"),
    ]
    for kwargs, match in bad_tracks:
        with pytest.raises(ParameterError, match=match):
            TracksStudyConfig(**kwargs)
    assert TracksStudyConfig(tracks=("oval",), controllers=("pp",), baseline=None).baseline is None
    # The car's training settings reach every job; each job takes its own seed.
    car = load_preset("f1tenth").with_training(data_laps=1, seed=9)
    job = TracksStudyConfig(tracks=("oval",), car=car, seeds=(1, 2)).job_config("oval", 2)
    assert job.car == car.with_training(seed=2) and job.plan().laps == 1 and job.seed == 2
    study = TracksStudy(TracksStudyConfig(tracks=("oval", "builtin"), car=car, seeds=(1, 2)))
    assert [j.name for j in study.jobs()] == [
        "oval seed 1",
        "oval seed 2",
        "builtin seed 1",
        "builtin seed 2",
    ]
    assert len({j.key for j in study.jobs()}) == 4
    bad_data = [
        ({"sizes": (10,)}, "below one window"),
        ({"sizes": ()}, "empty"),
        ({"controllers": ("lmpc",)}, "controllers"),
        ({"rkmpc_max_ratio": 1.5}, "rkmpc_max_ratio"),
        ({"min_laps": 3, "max_laps": 2}, "min_laps"),
        ({"track": "moon"}, "neither a built-in"),
        ({"car": "f1tenth"}, "DataStudyConfig.car must be a CarConfig"),
        ({"scale": -1.0}, "scale"),
    ]
    for kwargs, match in bad_data:
        with pytest.raises(ParameterError, match=match):
            DataStudyConfig(**kwargs)
    with pytest.raises(ParameterError, match="epochs"):  # the car's: refused where the car is made
        DataStudyConfig(car=load_preset("f1tenth").with_training(epochs=0))
    with pytest.raises(ParameterError, match="backend"):
        Parallel(backend="spark")
    with pytest.raises(ParameterError, match="n_jobs"):
        Parallel(n_jobs=0)
    with pytest.raises(ParameterError, match="an address is for a dask or ray cluster"):
        Parallel(address="tcp://1.2.3.4:8786")
