"""Studies over tracks and data sizes: small parallel runs, aggregation math, JSON, plots."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.analysis.statistics import RunGroup, summarise_runs
from rkmpc.analysis.study_plots import plot_data_study
from rkmpc.core.errors import ParameterError
from rkmpc.core.versions import versions
from rkmpc.experiments.studies.common import expand_tracks
from rkmpc.experiments.studies.data import DataStudyConfig, DataStudyResult, study_data, summarise_sizes
from rkmpc.experiments.studies.tracks import (
    TracksStudyConfig,
    TracksStudyResult,
    study_tracks,
    tracks_markdown,
)


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
    typed = study_tracks(cfg, n_jobs=2, progress=lambda o, done, total: seen.append((o.name, done, total)))
    result = typed.to_json()
    assert sorted(s[0] for s in seen) == ["builtin seed 0", "oval seed 0"]
    assert [s[1:] for s in sorted(seen, key=lambda s: s[1])] == [(1, 2), (2, 2)]
    json.dumps(result, allow_nan=False)
    assert result["tracks"] == ["builtin", "oval"] and result["seeds"] == [0]
    assert result["controllers"] == ["pp", "lmpc"] and result["baseline"] == "lmpc"
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
    cfg = DataStudyConfig(sizes=(350, 1400), seeds=(0,), epochs=1)
    typed = study_data(cfg, n_jobs=2)
    result = typed.to_json()
    json.dumps(result, allow_nan=False)
    assert result["sizes"] == [350, 1400] and result["seeds"] == [0]
    assert result["config"]["epochs"] == 1
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
    result = TracksStudyResult(cfg, {}, versions(), 0.0, summary, run_rows, [])
    md = tracks_markdown(result)
    assert "| rkmpc | 2/5 | 1 |" in md
    assert "FAILED: InputFileError: bad CSV" in md and "NO 40%" in md
    assert "| d | 0 | rkmpc | not driven |" in md
    no_base, _ = summarise_runs(jobs, ["rkmpc"], None)
    assert no_base["rkmpc"].change_pct == {}


def test_aggregate_data_by_hand():
    def job(controller, size, seed, lat=None, completed=True, ok=True):
        if not ok:
            return {"controller": controller, "size": size, "seed": seed, "ok": False, "metrics": {}}
        return {
            "controller": controller,
            "size": size,
            "seed": seed,
            "ok": True,
            "metrics": _metrics(lat, completed=completed, progress=1.0 if completed else 0.5),
            "augmented_count": size + 2 * seed,
            "raw_count": size // 3,
            "train_s": 1.0,
        }

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
    failed = [{**j, "error": "RuntimeError: boom"} if not j["ok"] else j for j in jobs]
    cfg = DataStudyConfig(seeds=(0, 1, 2))
    baseline = LapMetrics.from_json(_metrics(0.04))
    result = DataStudyResult(cfg, {}, versions(), 0.0, baseline, typed, failed)
    json.dumps(result.to_json(), allow_nan=False)
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
    bad_tracks = [
        ({"tracks": ()}, "empty"),
        ({"tracks": ("nowhere.csv",)}, "neither a built-in"),
        ({"tracks": ("oval",), "controllers": ("warp",)}, "unknown"),
        ({"tracks": ("oval",), "controllers": ("pp",)}, "baseline"),
        ({"tracks": ("oval",), "seeds": (0, 0)}, "repeat"),
        ({"tracks": ("oval",), "seeds": (-1,)}, "seeds"),
        ({"tracks": ("oval",), "study_options": {"seed": 3}}, "study_options"),
        ({"tracks": ("oval",), "scale": 0.0}, "scale"),
        ({"tracks": ("oval",), "vehicle": "bus"}, "vehicle"),
    ]
    for kwargs, match in bad_tracks:
        with pytest.raises(ParameterError, match=match):
            TracksStudyConfig(**kwargs)
    assert TracksStudyConfig(tracks=("oval",), controllers=("pp",), baseline=None).baseline is None
    assert TracksStudyConfig(tracks=("oval",), study_options={"laps": 1}).study_options == {"laps": 1}
    bad_data = [
        ({"sizes": (10,)}, "below one window"),
        ({"sizes": ()}, "empty"),
        ({"controllers": ("lmpc",)}, "controllers"),
        ({"rkmpc_max_ratio": 1.5}, "rkmpc_max_ratio"),
        ({"min_laps": 3, "max_laps": 2}, "min_laps"),
        ({"epochs": 0}, "epochs"),
        ({"track": "moon"}, "neither a built-in"),
    ]
    for kwargs, match in bad_data:
        with pytest.raises(ParameterError, match=match):
            DataStudyConfig(**kwargs)
    with pytest.raises(ParameterError, match="backend"):
        study_data(DataStudyConfig(sizes=(100,), seeds=(0,)), backend="spark")
