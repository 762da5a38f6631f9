"""Probe cases: messages, the newcomer's first hour, and the probe's graceful ones (that must stay so)."""

from __future__ import annotations

import io
import json
import re
from dataclasses import replace
from pathlib import Path
from unittest import mock

import numpy as np
from probe_cases import (
    CLEAR_ERROR,
    CORRECT,
    GRACEFUL,
    Evidence,
    Probe,
    case,
    caught_warnings,
    cli_error,
    ellipse,
    lap,
    models,
    raises,
    scenario,
    write_centerline,
)

MESSAGES = "messages"
NEWCOMER = "the newcomer's first hour"
HELD = "graceful in the probe (must stay so)"
README = Path(__file__).resolve().parents[2] / "README.md"


@case("msg.track_misspelt", MESSAGES, "--track bultin suggests the built-in names", CLEAR_ERROR)
def track_misspelt(probe: Probe) -> Evidence:
    args = ["run", "--controller", "pp", "--track", "bultin", "--out", str(probe.path("o"))]
    return cli_error(probe, args, "unknown track 'bultin'", "did you mean 'builtin'")


@case("msg.laps_zero", MESSAGES, "--laps 0 names the option, not an internal class", CLEAR_ERROR)
def laps_zero(probe: Probe) -> Evidence:
    args = ["run", "--controller", "lmpc", "--laps", "0", "--out", str(probe.path("o"))]
    evidence = cli_error(probe, args, "argument --laps", "got 0")
    assert "TrackStudy" not in evidence.message and not probe.path("o").exists()
    return evidence


@case(
    "msg.wrong_model_kind",
    MESSAGES,
    "a model file of the other kind says which it is, without numpy's allow_pickle advice",
    CLEAR_ERROR,
)
def wrong_model_kind(probe: Probe) -> Evidence:
    from rkmpc.learning.io import load_model, save_identified

    archive, identified = probe.path("residual.rkm"), probe.path("lmpc-id.json")
    models()["rkmpc"].save(archive)
    save_identified(models()["lmpc-id"], identified)
    first = raises(lambda: load_model(archive, "identified"), "residual.rkm", "--kind identified")
    second = raises(lambda: load_model(identified, "residual"), "lmpc-id.json", "JSON")
    for message in (first.message, second.message):
        assert "pickle" not in message, message
    return second


@case(
    "msg.nan_yaw_rate_in_data",
    MESSAGES,
    "a NaN yaw rate in training data names the file, the field and the row",
    CLEAR_ERROR,
)
def nan_yaw_rate_in_data(probe: Probe) -> Evidence:
    data = lap()
    obs = data.obs.copy()
    obs[37, 4] = np.nan
    path = probe.path("laps.npz")
    replace(data, obs=obs).save(path)
    args = ["train", "--data", str(path), "--kind", "residual", "--out", str(probe.path("m.rkm"))]
    return cli_error(probe, args, "laps.npz [obs.yaw_rate]", "row 37")


@case("msg.collect_seed_negative", MESSAGES, "collect --seed -5 names --seed", CLEAR_ERROR)
def collect_seed_negative(probe: Probe) -> Evidence:
    args = ["collect", "--seed", "-5", "--out", str(probe.path("d.npz"))]
    return cli_error(probe, args, "argument --seed", "-5")


@case("msg.bom_header", MESSAGES, "a UTF-8 byte-order mark before the header (Excel) is read", CORRECT)
def bom_header(probe: Probe) -> Evidence:
    from rkmpc.track.loaders import load_centerline

    plain = write_centerline(probe.path("plain.csv"), ellipse(20.0, 12.0), width=2.0)
    excel = probe.path("excel.csv")
    excel.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    a, b = load_centerline(plain), load_centerline(excel)
    assert a.centerline.length == b.centerline.length
    return Evidence(CORRECT, f"same track with and without the BOM ({b.centerline.length:.2f} m)")


@case(
    "msg.latitude_longitude",
    MESSAGES,
    "a file in latitude and longitude: says degrees (was 'reset steer exceeds the limit')",
    CLEAR_ERROR,
)
def latitude_longitude(probe: Probe) -> Evidence:
    th = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    lonlat = np.column_stack([11.55 + 0.006 * np.cos(th), 48.26 + 0.004 * np.sin(th)])
    track = write_centerline(probe.path("gps.csv"), lonlat, width=5.0)
    args = ["run", "--controller", "pp", "--track", str(track), "--out", str(probe.path("o"))]
    evidence = cli_error(probe, args, "gps.csv", "degrees (latitude, longitude)")
    assert "steer" not in evidence.message
    return evidence


@case(
    "msg.fullsize_on_builtin",
    MESSAGES,
    "--vehicle fullsize on the 1:10 built-in track is warned about",
    GRACEFUL,
)
def fullsize_on_builtin(_: Probe) -> Evidence:
    from rkmpc.sim.scenario import load_scenario

    with caught_warnings() as seen:
        load_scenario("builtin", vehicle="fullsize")
    said = [str(w.message) for w in seen if "1:10" in str(w.message)]
    assert said, [str(w.message) for w in seen]
    return Evidence(GRACEFUL, said[0])


@case("msg.jobs_beyond_jobs", MESSAGES, "--jobs 8 for one job starts one worker, not 8", CORRECT)
def jobs_beyond_jobs(_: Probe) -> Evidence:
    import math

    import rkmpc.experiments.parallel as parallel

    with mock.patch.object(parallel, "backend_config", wraps=parallel.backend_config) as spy:
        out = parallel.run_jobs([parallel.Job("hyp", math.hypot, (3.0, 4.0))], n_jobs=8, backend="loky")
    workers = [call.args[1] for call in spy.call_args_list]
    assert workers == [1] and out[0].value == 5.0, (workers, out)
    return Evidence(CORRECT, f"one job, --jobs 8: {workers[0]} worker")


# ------------------------------------------------------------------ the newcomer's first hour


@case("new.version", NEWCOMER, "rkmpc --version", CORRECT)
def version(probe: Probe) -> Evidence:
    from importlib.metadata import version as package_version

    run = probe.cli("--version")
    assert run.code == 0 and run.out.strip() == f"rkmpc {package_version('rkmpc')}", run
    return Evidence(CORRECT, run.out.strip())


@case("new.help_defaults", NEWCOMER, "--help shows each option's default", CORRECT)
def help_defaults(probe: Probe) -> Evidence:
    run = probe.cli("compare", "-h")
    text = " ".join(run.out.split())
    assert run.code == 0 and "(default: 2)" in text and "(default: 50000)" in text, text[:300]
    assert "(default: None)" not in text and "(default: False)" not in text
    found = re.search(r"--data-laps DATA_LAPS [^()]*\(default: 2\)", text)
    assert found, text[:500]
    return Evidence(CORRECT, found.group(0))


@case("new.collect_out_is_a_file", NEWCOMER, "collect --out says it is a file, not a folder", CORRECT)
def collect_out_is_a_file(probe: Probe) -> Evidence:
    run = probe.cli("collect", "-h")
    text = " ".join(run.out.split())
    found = re.search(r"--out OUT (output [^(]*\(\.npz\))", text)
    assert found and "folder" not in found.group(1), text[-1500:]
    return Evidence(CORRECT, found.group(0).strip())


@case("new.help_plain_text", NEWCOMER, "the top-level help shows no raw reST", CORRECT)
def help_plain_text(probe: Probe) -> Evidence:
    run = probe.cli("-h")
    assert run.code == 0
    for mark in ("``", ":func:", ":class:", ":mod:", ":data:", ".. "):
        assert mark not in run.out, mark
    description = " ".join(run.out.split("\n\n")[1].split())
    return Evidence(CORRECT, description)


@case(
    "new.readme_model_loading",
    NEWCOMER,
    "the README shows loading a trained model; make_controller('rkmpc') without one is a clear error",
    CLEAR_ERROR,
)
def readme_model_loading(_: Probe) -> Evidence:
    from rkmpc.control import make_controller

    text = README.read_text()
    assert "load_model(" in text and 'make_controller("rkmpc", sc.reference, sc.vehicle, model=' in text
    sc = scenario()
    evidence = raises(lambda: make_controller("rkmpc", sc.reference, sc.vehicle), "needs model=")
    assert "ResidualMPCBase" not in evidence.message
    return evidence


@case("new.table_80_columns", NEWCOMER, "the result table fits an 80-column terminal, no cell cut", CORRECT)
def table_80_columns(_: Probe) -> Evidence:
    from probe_cases import controller
    from rich.console import Console

    from rkmpc.analysis.metrics import lap_metrics
    from rkmpc.analysis.tables import rich_tables_fitting
    from rkmpc.sim.closed_loop import SimConfig, simulate
    from rkmpc.vehicle.registry import make_plant

    sc = scenario()
    results = {}
    for name in ("pp", "lmpc", "nmpc"):
        sim = simulate(
            make_plant("f1tenth"), controller(name), sc.track, sc.reference, SimConfig(max_time=0.3)
        )
        results[name] = lap_metrics(sim)
    console = Console(width=80, record=True, file=io.StringIO())
    for table in rich_tables_fitting(results, "builtin", width=80):
        console.print(table)
    lines = console.export_text().splitlines()
    assert max(len(line) for line in lines) <= 80 and "…" not in "\n".join(lines)
    return Evidence(
        CORRECT, f"{len(lines)} lines, widest {max(len(line) for line in lines)} columns, no cell cut"
    )


# ------------------------------------------------------------------ held up in the probe


@case(
    "held.loader_bad_csv",
    HELD,
    "track files with a missing column or a bad number: refused naming file, column and line",
    CLEAR_ERROR,
)
def loader_bad_csv(probe: Probe) -> Evidence:
    from rkmpc.track.loaders import load_centerline

    missing = probe.path("missing.csv")
    missing.write_text("# x_m,w_tr_right_m,w_tr_left_m\n1,1,1\n2,1,1\n3,1,1\n4,1,1\n")
    raises(lambda: load_centerline(missing), "missing.csv", "y_m")
    bad = write_centerline(probe.path("bad.csv"), ellipse(20.0, 12.0), width=2.0)
    lines = bad.read_text().splitlines()
    lines[5] = lines[5].replace(",", ",abc", 1)
    bad.write_text("\n".join(lines) + "\n")
    return raises(lambda: load_centerline(bad), "bad.csv", "line 6")


@case(
    "held.atomic_writes",
    HELD,
    "a write that fails half-way leaves the old file whole and no temporary file",
    GRACEFUL,
)
def atomic_writes(probe: Probe) -> Evidence:
    from rkmpc.core.io import atomic_write

    path = probe.path("results.json")
    path.write_text('{"old": true}')
    try:
        with atomic_write(path) as handle:
            handle.write('{"new": ')
            raise KeyboardInterrupt  # as a kill or Ctrl-C half-way
    except KeyboardInterrupt:
        pass
    assert json.loads(path.read_text()) == {"old": True}
    assert [p.name for p in probe.tmp.iterdir()] == ["results.json"]
    return Evidence(GRACEFUL, "old file intact, no temporary file left")


@case(
    "held.no_pickle",
    HELD,
    "an .npz holding a pickled object is refused, never unpickled (allow_pickle=False)",
    CLEAR_ERROR,
)
def no_pickle(probe: Probe) -> Evidence:
    from rkmpc.learning.data.dataset import TransitionDataset

    good = probe.path("laps.npz")
    lap().save(good)
    with np.load(good, allow_pickle=False) as archive:  # what rkmpc writes needs no pickle
        assert {"obs", "next_obs", "metadata"} <= set(archive.files)
    evil = probe.path("evil.npz")
    np.savez(evil, obs=np.array([{"a": 1}], dtype=object))
    evidence = raises(lambda: TransitionDataset.load(evil), "evil.npz [obs]", "pickled Python objects")
    assert "damaged" not in evidence.message
    return evidence


@case(
    "held.faults_no_crash",
    HELD,
    "every named fault (noise, delay, friction, heavy): no controller crashes",
    GRACEFUL,
)
def faults_no_crash(_: Probe) -> Evidence:
    from probe_cases import controller

    from rkmpc.sim.closed_loop import SimConfig, simulate
    from rkmpc.sim.faults import apply_fault
    from rkmpc.vehicle.registry import make_plant

    sc = scenario()
    outcomes = []
    for fault in ("noise", "delay", "friction", "heavy"):
        for name in ("pp", "lmpc", "rkmpc"):
            plant = apply_fault(make_plant("f1tenth"), fault, sc, seed=0)
            result = simulate(plant, controller(name), sc.track, sc.reference, SimConfig(max_time=1.0))
            counts = result.log.metadata["status_counts"]
            assert result.outcome == "timeout", (fault, name, result.outcome)  # drove to the time limit
            assert not {"exception", "nonfinite_command"} & set(counts), (fault, name, counts)
            outcomes.append(f"{fault}/{name}")
    return Evidence(GRACEFUL, f"{len(outcomes)} runs of 1 s ({', '.join(outcomes[:3])}, ...): none crashed")
