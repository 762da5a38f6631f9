"""Issue 27's probe: a newcomer's first week (set-up, piped output, help, tables, messages, figures)."""

from __future__ import annotations

import re
from pathlib import Path
from unittest import mock

from probe_cases import CORRECT, GRACEFUL, Evidence, Probe, case, identified_model, lap, raises, scenario

GROUP = "a newcomer's friction (issue 27)"
ROOT = Path(__file__).resolve().parents[2]


@case(
    "friction.readme_setup",
    GROUP,
    "the README says `make test` needs cmake and a C/C++ compiler",
    CORRECT,
    problem="friction",
)
def readme_setup(_: Probe) -> Evidence:
    text = " ".join((ROOT / "README.md").read_text().split())
    found = re.search(r"`make test` also builds[^.]*cmake[^.]*C/C\+\+ compiler[^.]*\.", text)
    assert found, "the README's set-up says nothing of cmake"
    return Evidence(CORRECT, found.group(0))


@case(
    "friction.piped_tables",
    GROUP,
    "piped output (make demo > log) prints tables at most 100 characters wide (were 228-260)",
    CORRECT,
    problem="friction",
)
def piped_tables(probe: Probe) -> Evidence:
    args = ["compare", "--controllers", "pp,lmpc", "--track", "oval", "--also-sensors", "none"]
    run = probe.cli(*args, "--out", str(probe.path("o")))
    assert run.code == 0, run.err[-500:]
    widest = max(len(line) for line in run.out.splitlines())
    assert widest <= 100 and "lat. err (m)" in run.out, widest
    return Evidence(CORRECT, f"{len(run.out.splitlines())} lines on stdout, widest {widest} characters")


def _help(probe: Probe, *argv: str) -> str:
    run = probe.cli(*argv, "-h")
    assert run.code == 0
    return " ".join(run.out.split())


@case(
    "friction.help_gaps",
    GROUP,
    "help of --laps, --scale (studies, learn-pace), train --data, collect --controller, study pace "
    "--controllers (nmpc-dynamic's time), --cache-dir ($XDG_CACHE_HOME)",
    CORRECT,
    problem="friction",
    see_also=("tests/cli/test_help.py::test_every_option_of_every_command_has_help",),
)
def help_gaps(probe: Probe) -> Evidence:
    for command in (("run",), ("compare",)):
        assert re.search(r"--laps LAPS laps each controller drives \(default: 1\)", _help(probe, *command))
    collect = _help(probe, "collect")
    assert "--laps LAPS laps of data to record (default: 2)" in collect  # as the README uses
    assert "--controller {pp,lmpc} the controller that drives the laps" in collect
    assert re.search(r"--data DATA the data set \(\.npz", _help(probe, "train"))
    for command in (
        ("study", "tracks"),
        ("study", "cars"),
        ("study", "data"),
        ("study", "pace"),
        ("learn-pace",),
    ):
        assert "--scale SCALE scale of track files" in _help(probe, *command), command
    pace = _help(probe, "study", "pace")
    assert "nmpc-dynamic; nmpc-dynamic's climb takes 6-15 minutes per real track" in pace
    cache = "$RKMPC_CACHE_DIR, else $XDG_CACHE_HOME/rkmpc, else ~/.cache/rkmpc"
    assert cache in _help(probe, "compare")
    docs = " ".join((ROOT / "docs" / "experiments.md").read_text().split())
    assert "`$XDG_CACHE_HOME/rkmpc`" in docs
    return Evidence(CORRECT, f"every option has help; --cache-dir: {cache}")


@case(
    "friction.slide_flagged",
    GROUP,
    "peak a_y 19.1 m/s² on a lap marked done with a 5 m/s² limit: flagged in the table",
    GRACEFUL,
    problem="friction",
)
def slide_flagged(_: Probe) -> Evidence:
    from rkmpc.analysis.tables import markdown_table

    keys = ("lateral_error_mean_m", "lateral_error_max_m", "heading_error_mean_rad", "steer_rate_mean_rad_s")
    base = dict.fromkeys(keys, 0.05) | {"command_rate_mean_rad_s": 0.3, "solve_ms_mean": 0.2}
    base |= {"solve_ms_p99": 0.5, "solve_ms_max": 0.7, "lap_time_s": 25.0, "fallback_count": 0, "steps": 500}
    base |= {"completed": True, "progress": 1.0}
    results = {
        "lmpc": base | {"lateral_accel_max_m_s2": 6.1},
        "rkmpc": base | {"lateral_accel_max_m_s2": 19.1},
    }
    text = markdown_table(results, lateral_limit=5.0)
    assert "| 19.1 ! |" in text and "| 6.1 |" in text, text
    note = text.rstrip().splitlines()[-1]
    assert note.startswith("! peak a_y beyond 2 x the pace's lateral limit (5 m/s²)") and "(rkmpc)" in note
    return Evidence(GRACEFUL, note)


@case(
    "friction.heldout_error_unit",
    GROUP,
    "train's 'held-out prediction error' says what it measures and in which units",
    CORRECT,
    problem="friction",
)
def heldout_error_unit(probe: Probe) -> Evidence:
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.contract import Provenance

    sc = scenario()
    made_for = Provenance(vehicle="f1tenth", dt=0.05, wheelbase=sc.vehicle.wheelbase)
    lines = train_to_file(lap(), made_for, sc.vehicle, "paper", probe.path("m.rkm"), epochs=2)
    (line,) = [x for x in lines if x.startswith("held-out prediction error")]
    assert (
        line.startswith("held-out prediction error (norm of x (m), y (m), yaw (rad)): ")
        and "at step 1" in line
    )
    assert not [x for x in lines if "epoch" in x]  # no training progress in what is printed (table2.md)
    return Evidence(CORRECT, line)


@case(
    "friction.table2_no_progress",
    GROUP,
    "car-loop's table2.md: a model's lines, not the 11 training progress lines joined with ';'",
    CORRECT,
    problem="friction",
)
def table2_no_progress(probe: Probe) -> Evidence:
    from types import SimpleNamespace

    from rkmpc.config.loader import load_preset
    from rkmpc.ros.workflow import _learn

    (probe.tmp / "data").mkdir()
    lap().save(probe.tmp / "data" / "laps.npz")
    run = SimpleNamespace(
        out=probe.tmp, commands=[], car=load_preset("f1tenth"), config=SimpleNamespace(seed=0)
    )
    with mock.patch("rkmpc.experiments.training.train_to_file", return_value=["a model -> m.rkm"]) as train:
        text = _learn(run, "residual", probe.path("m.rkm"))  # type: ignore[arg-type]
    assert "on_epoch" not in train.call_args.kwargs or train.call_args.kwargs["on_epoch"] is None
    return Evidence(CORRECT, f"trained without progress lines: {text!r}")


@case(
    "friction.mismatch_hint",
    GROUP,
    "the contract error's way out: allow_mismatch=True in the library, --allow-mismatch on the command line",
    CORRECT,
    problem="friction",
)
def mismatch_hint(probe: Probe) -> Evidence:
    from dataclasses import replace

    from rkmpc.core.errors import ContractError
    from rkmpc.sim.build import check_model

    model = identified_model(probe)
    other = replace(scenario(), dt=0.1)
    library = raises(lambda: check_model(model, other, source="id.json"), types=(ContractError,))
    assert (
        library.message.endswith("(pass allow_mismatch=True to use it anyway)")
        and "--allow" not in library.message
    )
    data = probe.path("lap.npz")
    lap().save(data)
    run = probe.cli(
        "train",
        "--data",
        str(data),
        "--kind",
        "identified",
        "--dt",
        "0.1",
        "--out",
        str(probe.path("i.json")),
    )
    assert run.code == 2 and run.err.rstrip().endswith("(give --allow-mismatch to use it anyway)"), run.err
    assert "allow_mismatch=" not in run.err
    return Evidence(CORRECT, f"library: ...{library.message[-45:]}; command line: ...{run.err.strip()[-40:]}")


@case(
    "friction.demo_figures",
    GROUP,
    "the demo plot: lmpc drawn over nmpc, lmpc-id wide; solve_times.png flags a step beyond the period",
    CORRECT,
    problem="friction",
)
def demo_figures(_: Probe) -> Evidence:
    import matplotlib.pyplot as plt

    from rkmpc.analysis.plots import plot_solve_times
    from rkmpc.analysis.styles import CONTROLLER_STYLE
    from rkmpc.sim.closed_loop import SimConfig, simulate
    from rkmpc.vehicle.registry import make_plant

    style = CONTROLLER_STYLE
    assert style["nmpc"].zorder < style["lmpc"].zorder < style["lmpc-id"].zorder < style["rkmpc"].zorder
    assert style["lmpc-id"].linewidth > style["kmpc"].linewidth
    from probe_cases import controller

    sc = scenario()
    log = simulate(
        make_plant("f1tenth"), controller("lmpc"), sc.track, sc.reference, SimConfig(max_time=0.5)
    ).log
    log["solve_time_s"][3] = 0.063
    ax = plot_solve_times({"lmpc": log}, period_s=0.05).axes[0]
    (flag,) = [t.get_text() for t in ax.texts if "beyond" in t.get_text()]
    plt.close("all")
    return Evidence(CORRECT, f"lmpc over nmpc (zorder); solve_times: '{flag}'")
