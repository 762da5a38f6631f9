"""The pace study and learning to race: the ladder, the clean-lap rule, data provenance, the CLI."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pytest
from matplotlib.figure import Figure

import rkmpc.experiments.studies.learn_pace as learn_mod
import rkmpc.experiments.studies.pace_job as job_mod
from rkmpc.analysis.metrics import LapMetrics
from rkmpc.analysis.study_plots import plot_learn_pace, plot_pace_study
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.studies.learn_pace import LearnPaceConfig, LearnPaceStudy
from rkmpc.experiments.studies.pace import PaceStudy, PaceStudyResult
from rkmpc.experiments.studies.pace_job import PaceStep, PaceStudyConfig, pace_job
from rkmpc.experiments.studies.pace_rules import (
    MAX_FALLBACK_SHARE,
    check_ladder,
    data_verdict,
    lap_verdict,
    pace_ladder,
)
from rkmpc.experiments.study import run_study

LADDER = ((4.0, 3.5), (5.0, 4.0), (6.0, 5.0), (7.0, 6.0), (8.0, 7.0))


def study_pace(cfg: PaceStudyConfig) -> PaceStudyResult:
    return run_study(PaceStudy(cfg))


def learn_pace(cfg: LearnPaceConfig):
    return run_study(LearnPaceStudy(cfg))


# ---------------------------------------------------------------------------
# the ladder and the clean-lap rule


def test_default_ladder_climbs_from_the_preset_pace_to_the_cars_top_speed():
    ladder = pace_ladder("f1tenth")
    assert ladder[0] == (4.0, 3.5) and ladder[1] == (4.5, 4.0)
    # 40 steps of 0.5 m/s^2: on beyond the tyres' grip, the 1:10 car topping out at 8 m/s.
    assert ladder[-2:] == ((23.5, 8.0), (24.0, 8.0))
    assert len(ladder) == 41
    assert pace_ladder("f1tenth", start=(5.0, 4.0), step=(1.0, 0.0), steps=2) == ((5, 4), (6, 4), (7, 4))
    assert pace_ladder("fullsize")[0] == (5.0, 25.0)


@pytest.mark.parametrize(
    "paces",
    [(), [(4.0, 3.5), (3.5, 4.0)], [(4.0, 3.5), (4.0, 3.5)], [(0.0, 3.5)], [(4.0,)], "4:3.5"],
)
def test_a_ladder_must_climb(paces):
    with pytest.raises(ParameterError):
        check_ladder("paces", paces)


def _verdict(**kw: Any) -> str | None:
    base = {
        "completed": True,
        "outcome": "completed",
        "progress": 1.0,
        "fallback_count": 0,
        "steps": 100,
        "status_counts": {"ok": 100},
    }
    return lap_verdict(**{**base, **kw})


def test_clean_lap_rule():
    assert _verdict() is None
    assert _verdict(completed=False, outcome="off_track", progress=0.44) == "off_track at 44%"
    assert _verdict(fallback_count=2) is None  # 2 % is allowed
    assert MAX_FALLBACK_SHARE == 0.02
    assert "fall-backs" in str(_verdict(fallback_count=3))
    assert "inadmissible" in str(_verdict(fallback_count=1, status_counts={"ok": 99, "inadmissible": 1}))
    meta = {"completed": False, "outcome": "timeout", "progress_laps": 1.0, "laps": 2, "fallback_count": 0}
    assert data_verdict({**meta, "steps": 10, "status_counts": {}}) == "timeout at 50%"


def test_configs_refuse_bad_settings():
    with pytest.raises(ParameterError, match="unknown"):
        PaceStudyConfig(tracks=("builtin",), controllers=("warp",))
    with pytest.raises(ParameterError):
        PaceStudyConfig(tracks=("builtin",), paces=((5.0, 4.0), (4.0, 3.5)))
    with pytest.raises(ParameterError):
        PaceStudyConfig(tracks=("nowhere.csv",))
    laps_only = r"learn from laps of the track \(lmpc-id, nmpc-id, rkmpc-paper, rkmpc\)"
    with pytest.raises(ParameterError, match=laps_only):
        LearnPaceConfig(controller="kmpc")
    with pytest.raises(ParameterError, match="at least one faster"):
        LearnPaceConfig(paces=((4.0, 3.5),))
    with pytest.raises(ParameterError, match=r"PaceStudyConfig\.car must be a CarConfig"):
        PaceStudyConfig(tracks=("builtin",), car="f1tenth")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=r"LearnPaceConfig\.scale"):
        LearnPaceConfig(scale=-1.0)
    assert PaceStudyConfig(tracks="builtin").ladder == pace_ladder("f1tenth")
    # The car's own pace starts its ladder; its training settings are the study's.
    fast = load_preset("f1tenth").at_pace(6.0, 5.0).with_training(seed=4)
    cfg = PaceStudyConfig(tracks="builtin", car=fast)
    assert cfg.ladder[0] == (6.0, 5.0) and cfg.seed == 4
    assert cfg.scenario("builtin", (5.0, 4.5)).limits == fast.limits.at_pace(5.0, 4.5)
    learn = LearnPaceConfig(car=fast)
    assert learn.study().car == fast and learn.study().paces == learn.paces


# ---------------------------------------------------------------------------
# synthetic climbs: which data each model learned from, where the climb stops


@dataclass
class _Result:
    completed: bool
    outcome: str
    progress: float
    fallback_count: int = 0
    status_counts: dict[str, int] = field(default_factory=lambda: {"ok": 100})
    log: list[int] = field(default_factory=lambda: [0] * 100)


@dataclass
class _Data:
    clean: bool
    who: str
    pace: float
    n: int = 100

    @property
    def metadata(self) -> dict[str, Any]:
        return {
            "completed": self.clean,
            "outcome": "completed" if self.clean else "off_track",
            "progress_laps": 2.0 if self.clean else 0.5,
            "laps": 2,
            "fallback_count": 0,
            "steps": 100,
            "status_counts": {"ok": 100},
        }

    def __len__(self) -> int:
        return self.n

    def content_hash(self) -> str:
        return f"{self.who}@{self.pace}"


@dataclass
class _Record:
    """What the stand-in learner says it made (a ModelRecord's JSON)."""

    kind: str

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind}


class _Pool:
    @staticmethod
    def concatenate(parts: list[_Data]) -> _Data:
        return _Data(True, "pool", 0.0, sum(len(p) for p in parts))


def _metrics(clean: bool, lateral: float) -> LapMetrics:
    return LapMetrics(
        completed=clean,
        progress=1.0 if clean else 0.5,
        lap_time_s=100.0 / lateral if clean else None,
        lateral_error_mean_m=0.01 * lateral,
        lateral_error_max_m=0.05 * lateral,
        heading_error_mean_rad=0.01,
        steer_rate_mean_rad_s=0.1,
        command_rate_mean_rad_s=0.1,
        solve_ms_mean=1.0,
        solve_ms_p99=1.0,
        solve_ms_max=1.0,
        fallback_count=0,
        steps=100,
        lateral_accel_max_m_s2=None,
        status_counts={"ok": 100},
    )


@pytest.fixture
def synthetic(monkeypatch):
    """LMPC clean up to 4 m/s^2, the learned controller up to 6: records every call."""
    calls: dict[str, list[Any]] = {"record": [], "train": []}

    def record(scenario, spec, *, model=None):
        lateral = scenario.limits.lateral_accel
        clean = lateral <= (4.0 if spec.controller == "lmpc" else 6.0)
        calls["record"].append((spec.controller, lateral, model))
        result = _Result(clean, "completed" if clean else "off_track", 2.0 if clean else 0.5)
        return result, _Data(clean, spec.controller, lateral)

    def make_model(recipe, scenario, data, data_key, *, seed, epochs=None, cache=None, say=None):
        calls["train"].append((scenario.limits.lateral_accel, len(data())))
        return f"model@{scenario.limits.lateral_accel:g}", _Record(recipe.kind)

    def run_controller(scenario, spec, *, model=None, allow_mismatch=False):
        lateral = scenario.limits.lateral_accel
        clean = lateral <= (4.0 if spec.controller == "lmpc" else 6.0)
        result = _Result(clean, "completed" if clean else "off_track", 1.0 if clean else 0.5)
        return result, _metrics(clean, lateral)

    for mod in (job_mod, learn_mod):
        monkeypatch.setattr(mod, "record", record)
        monkeypatch.setattr(mod, "make_model", make_model)
    monkeypatch.setattr(job_mod, "run_controller", run_controller)
    monkeypatch.setattr(learn_mod, "TransitionDataset", _Pool)
    monkeypatch.setattr(learn_mod, "lap_metrics", lambda result, laps: _metrics(result.completed, 5.0))
    return calls


def test_the_climb_stops_at_the_first_unclean_pace_and_records_its_data(synthetic):
    cfg = PaceStudyConfig(tracks=("builtin",), controllers=("rkmpc",), paces=LADDER, use_cache=False)
    steps = pace_job(cfg, "builtin", "rkmpc")
    assert [s.pace for s in steps] == list(LADDER[:4])  # 8 m/s^2 is never tried
    assert [s.clean for s in steps] == [True, True, True, False]
    assert steps[-1].reason == "off_track at 50%"
    sources = [s.data for s in steps]
    assert all(d is not None for d in sources)
    # At 4 m/s^2 the LMPC is clean: its laps; above, the controller's own laps at the new pace,
    # driven with the model of its last clean pace.
    assert (sources[0].recorder, sources[0].recorder_pace, sources[0].lmpc_clean) == ("lmpc", None, True)
    assert [(d.recorder, d.recorder_pace) for d in sources[1:]] == [
        ("rkmpc", (4.0, 3.5)),
        ("rkmpc", (5.0, 4.0)),
        ("rkmpc", (6.0, 5.0)),
    ]
    assert all(
        d.pace == s.pace and d.lmpc_clean is False for d, s in zip(sources[1:], steps[1:], strict=True)
    )
    own = [(lat, model) for who, lat, model in synthetic["record"] if who == "rkmpc"]
    assert own == [(5.0, "model@4"), (6.0, "model@5"), (7.0, "model@6")]


def test_baselines_climb_without_data_and_the_study_compares_best_laps(synthetic):
    cfg = PaceStudyConfig(tracks=("builtin",), controllers=("lmpc", "rkmpc"), paces=LADDER, use_cache=False)
    result = study_pace(cfg)
    lmpc, rk = result.runs
    assert [s.data for s in lmpc.steps] == [None, None] and lmpc.stopped().pace == (5.0, 4.0)
    assert lmpc.best().pace == (4.0, 3.5) and rk.best().pace == (6.0, 5.0)
    assert result.change_pct(rk, "lmpc") == pytest.approx(100 * (100 / 6 - 25) / 25)
    data = json.loads(json.dumps(result.to_json()))
    assert data["best"][1]["pace"] == [6.0, 5.0] and data["best"][1]["stopped_at"] == [7.0, 6.0]
    assert data["runs"][1]["steps"][1]["data"]["recorder"] == "rkmpc"
    assert data["seed"] == 0 and "versions" in data and data["ladder"][0] == [4.0, 3.5]
    text = result.to_markdown()
    assert "| builtin | rkmpc | 16.67 | 6/5 |" in text and "model of 5/4" in text
    assert isinstance(plot_pace_study(result.series(), "t"), Figure)


def test_learn_pace_pools_clean_laps_and_stops_at_an_unclean_one(synthetic):
    result = learn_pace(LearnPaceConfig(paces=LADDER, use_cache=False))
    its = result.iterations
    assert [(it.controller, it.pace[0], it.clean) for it in its] == [
        ("lmpc", 4.0, True),
        ("rkmpc", 5.0, True),
        ("rkmpc", 6.0, True),
        ("rkmpc", 7.0, False),
    ]
    assert [len(it.trained_on or []) for it in its] == [0, 1, 2, 3]
    assert [it.pool_samples for it in its[1:]] == [100, 200, 300]
    assert its[3].trained_on[2] == {"recorder": "rkmpc", "pace": [6.0, 5.0], "samples": 100}
    assert synthetic["train"] == [(5.0, 100), (6.0, 200), (7.0, 300)]
    assert result.stopped.startswith("laps at 7/6 not clean")
    assert json.loads(json.dumps(result.to_json()))["iterations"][3]["clean"] is False
    assert "| 3 | rkmpc | 7/6 | no: off_track at 25% |" in result.to_markdown()
    capped = learn_pace(LearnPaceConfig(paces=LADDER, use_cache=False, max_iterations=1))
    assert len(capped.iterations) == 2 and "max_iterations" in capped.stopped
    figure = plot_learn_pace(["4/3.5", "5/4"], [27.0, None], [True, False], [27.0, 24.0], [0.02, 0.1], "t")
    assert isinstance(figure, Figure)
    # A climb to the top of the ladder (41 iterations) keeps its pace labels readable: every k-th.
    n = 41
    long = plot_learn_pace([f"{i}/8" for i in range(n)], [20.0] * n, [True] * n, [None] * n, [0.1] * n, "t")
    ticks = [t.get_text() for t in long.axes[0].get_xticklabels()]
    assert len(ticks) <= 11 and ticks[0] == "0\n0/8" and ticks[-1] == "40\n40/8"


def test_learn_pace_climbs_with_every_controller_that_learns_from_laps(synthetic):
    # nmpc-id identifies its tyres from the pool as lmpc-id identifies its servo: the same loop,
    # the recipe's own model kind, the CLI's choices from the same list.
    from rkmpc.cli import build_parser

    result = learn_pace(LearnPaceConfig(controller="nmpc-id", paces=LADDER, use_cache=False))
    assert [(it.controller, it.pace[0]) for it in result.iterations][1:] == [
        ("nmpc-id", 5.0),
        ("nmpc-id", 6.0),
        ("nmpc-id", 7.0),
    ]
    assert {it.model["kind"] for it in result.iterations[1:]} == {"identified-tyres"}
    args = build_parser().parse_args(["learn-pace", "--controller", "nmpc-id", "--out", "x"])
    assert args.controller == "nmpc-id"


def test_learn_pace_stops_where_its_model_is_refused(synthetic, monkeypatch):
    from rkmpc.core.errors import NotLearnedError

    def refuse_above_5(recipe, scenario, data, data_key, *, seed, epochs=None, cache=None, say=None):
        if scenario.limits.lateral_accel > 5.0:
            raise NotLearnedError("the pool", recipe.kind, "worse than no correction")
        return "model", _Record(recipe.kind)

    monkeypatch.setattr(learn_mod, "make_model", refuse_above_5)
    result = learn_pace(LearnPaceConfig(paces=LADDER, use_cache=False))
    assert [(it.controller, it.pace[0], it.clean) for it in result.iterations] == [
        ("lmpc", 4.0, True),
        ("rkmpc", 5.0, True),
    ]
    assert result.stopped == "no model at 6/5: worse than no correction"


def test_the_cli_climbs_from_the_car_files_pace_and_records_the_file(synthetic, tmp_path):
    from rkmpc.cli import main

    race = Path(__file__).resolve().parents[3] / "configs" / "f1tenth-race.toml"
    out = tmp_path / "pace"
    argv = ["study", "pace", "--tracks", "builtin", "--controllers", "rkmpc", "--config", str(race)]
    assert main([*argv, "--steps", "2", "--seed", "5", "--jobs", "1", "--out", str(out)]) == 0
    data = json.loads((out / "study_pace.json").read_text())
    assert data["ladder"] == [[6.0, 5.0], [6.5, 5.5], [7.0, 6.0]]  # from the file's own pace
    car = data["config"]["car"]
    assert car["file"] == str(race.resolve()) and car["limits"]["brake_decel"] == 3.75
    assert car["training"]["seed"] == 5 == data["seed"]  # the flag's
    # the synthetic rkmpc is clean up to 6 m/s^2: the file's pace, then the climb stops
    assert [s["clean"] for s in data["runs"][0]["steps"]] == [True, False]
    learn = tmp_path / "learn"
    argv = ["learn-pace", "--config", str(race), "--start", "4:3.5", "--step", "1:0.5", "--steps", "2"]
    assert main([*argv, "--laps", "3", "--out", str(learn)]) == 0
    data = json.loads((learn / "learn_pace.json").read_text())
    assert [it["pace"] for it in data["iterations"]] == [[4.0, 3.5], [5.0, 4.0], [6.0, 4.5]]
    car = data["config"]["car"]
    assert car["file"] == str(race.resolve()) and car["training"]["data_laps"] == 3  # the flag's


# ---------------------------------------------------------------------------
# real runs, small


def test_recorded_data_carry_the_step_count_and_statuses(builtin_lap):
    meta = builtin_lap.metadata
    assert meta["steps"] >= len(builtin_lap) and sum(meta["status_counts"].values()) == meta["steps"]
    assert data_verdict(meta) is None


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
def test_small_pace_study_on_the_builtin_track():
    cfg = PaceStudyConfig(
        tracks=("builtin",),
        controllers=("lmpc", "rkmpc"),
        paces=((4.0, 3.5), (6.0, 5.0)),
        car=load_preset("f1tenth").with_training(epochs=2),
        use_cache=False,
    )
    result = study_pace(cfg)
    lmpc, rk = result.runs
    assert lmpc.ok and rk.ok and lmpc.steps[0].clean and rk.steps[0].clean
    first = rk.steps[0].data
    assert first is not None and first.recorder == "lmpc" and first.samples > 0
    if len(rk.steps) > 1:
        second = rk.steps[1].data
        assert second is not None
        assert second.recorder == ("lmpc" if second.lmpc_clean else "rkmpc")
    json.dumps(result.to_json())


@pytest.mark.slow
def test_cli_study_pace_and_learn_pace(tmp_path, capsys):
    from rkmpc.cli import main

    out = tmp_path / "pace"
    argv = ["study", "pace", "--tracks", "builtin", "--controllers", "lmpc,rkmpc", "--paces", "4:3.5,5:4.5"]
    assert (
        main([*argv, "--epochs", "2", "--jobs", "1", "--cache-dir", str(tmp_path / "c"), "--out", str(out)])
        == 0
    )
    data = json.loads((out / "study_pace.json").read_text())
    assert data["ladder"] == [[4.0, 3.5], [5.0, 4.5]] and len(data["runs"]) == 2
    assert (out / "study_pace.md").is_file() and (out / "study_pace.png").is_file()
    learn = tmp_path / "learn"
    argv = ["learn-pace", "--paces", "4:3.5,5:4.5", "--epochs", "2", "--max-iterations", "1"]
    assert main([*argv, "--cache-dir", str(tmp_path / "c"), "--out", str(learn)]) == 0
    data = json.loads((learn / "learn_pace.json").read_text())
    assert [it["iteration"] for it in data["iterations"]] == [0, 1]
    assert (learn / "learn_pace.png").is_file() and "Learning to race" in capsys.readouterr().out
    assert main(["learn-pace", "--paces", "4:3.5", "--start", "4:3.5", "--out", str(tmp_path / "x")]) == 2


def test_a_journal_resumes_the_pace_study_and_widens_it(synthetic, tmp_path, capsys):
    from rkmpc.cli import main

    journal = tmp_path / "journal"
    argv = ["study", "pace", "--tracks", "builtin", "--steps", "3", "--jobs", "1", "--journal", str(journal)]
    assert main([*argv, "--controllers", "rkmpc", "--out", str(tmp_path / "a")]) == 0
    first = json.loads((tmp_path / "a" / "study_pace.json").read_text())
    climbed = len(synthetic["record"])
    assert climbed > 0
    # More controllers, same settings: the rkmpc climb comes from the journal, only the LMPC runs.
    assert main([*argv, "--controllers", "lmpc,rkmpc", "--out", str(tmp_path / "b")]) == 0
    assert len(synthetic["record"]) == climbed
    assert "builtin rkmpc: " in capsys.readouterr().err
    second = json.loads((tmp_path / "b" / "study_pace.json").read_text())
    assert second["runs"][1]["steps"] == first["runs"][0]["steps"]
    assert [r["controller"] for r in second["runs"]] == ["lmpc", "rkmpc"]
    # Another seed is another study: refused before anything runs, naming the setting.
    assert main([*argv, "--controllers", "rkmpc", "--seed", "3", "--out", str(tmp_path / "c")]) != 0
    err = capsys.readouterr().err
    assert "differing: settings.car.training.seed)" in err and not (tmp_path / "c").exists()


def test_steps_read_back_from_the_result_file_are_the_steps(synthetic):
    cfg = PaceStudyConfig(tracks=("builtin",), controllers=("lmpc", "rkmpc"), paces=LADDER, use_cache=False)
    result = study_pace(cfg)
    data = json.loads(json.dumps(result.to_json()))
    for run, record in zip(result.runs, data["runs"], strict=True):
        assert [PaceStep.from_json(s) for s in record["steps"]] == run.steps
    assert any(s.data is not None and s.data.recorder_pace is not None for s in result.runs[1].steps)


def test_a_long_ladder_names_at_most_ten_paces_on_its_axis_first_and_last_included():
    from rkmpc.analysis.study_plots import MAX_PACE_TICKS, PaceSeries

    paces = [(4.0 + 0.5 * i, 3.0 + 0.25 * i) for i in range(20)]
    series = PaceSeries(
        controller="lmpc",
        track="builtin",
        paces=paces,
        lap_time=[30.0 - 0.5 * i for i in range(20)],
        lateral=[0.01 + 0.001 * i for i in range(20)],
        reference_lap_time=30.0,
        best_index=19,
    )
    fig = plot_pace_study([series], "t")
    for ax in fig.axes:
        ticks = list(ax.get_xticks())
        assert 2 <= len(ticks) <= MAX_PACE_TICKS
        assert ticks[0] == 4.0 and ticks[-1] == paces[-1][0]
    short = plot_pace_study(
        [replace(series, paces=paces[:5], lap_time=[30.0] * 5, lateral=[0.01] * 5, best_index=0)], "t"
    )
    assert list(short.axes[0].get_xticks()) == [p[0] for p in paces[:5]]
