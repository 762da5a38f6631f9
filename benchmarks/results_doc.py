"""Write docs/results.md from the outputs of a full run.

Run: ``make results`` (which first runs the demo, the fault comparisons, both
studies and the step-time benchmark), or
``python benchmarks/results_doc.py --demo runs/demo --tracks runs/study-tracks
--data runs/study-data --bench runs/bench/step_times.json --faults runs/faults
--out docs/results.md``. Figures are copied next to the document (in
``docs/results/``); a hand-written discussion, when ``--notes`` names one, is
placed at the top verbatim. Every number comes from the files read: the JSON results, and the
studies' own Markdown tables (``study_tracks.md``, ``study_data.md``, written by ``rkmpc study``
from the same result as its JSON).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
from pathlib import Path
from typing import Any

from rkmpc.analysis.tables import fault_table, markdown_table
from rkmpc.core.io import write_text_atomic

#: The paper's Matlab step times (mean, max) in ms, from its Table I.
PAPER_MS = {"lmpc": (2.38, 13.30), "nmpc": (13.68, 66.38), "kmpc": (3.78, 17.58), "rkmpc": (6.73, 16.14)}


def _load(path: Path) -> Any:
    return json.loads(path.read_text())


def _figure(src: Path, fig_dir: Path, name: str, doc: Path) -> str:
    fig_dir.mkdir(parents=True, exist_ok=True)
    dst = fig_dir / name
    shutil.copyfile(src, dst)
    return os.path.relpath(dst, doc.parent)


def _versions(versions: dict[str, str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in versions.items())


def demo_section(demo: Path, fig_dir: Path, doc: Path) -> list[str]:
    """Table I on the built-in track, with its figures."""
    res = _load(demo / "results.json")
    training = res["training"]
    lines = [
        "## Table I on the built-in track (`make demo`)",
        "",
        f"`rkmpc compare --track builtin --out runs/demo`, seed {res['config']['seed']}; "
        f"versions: {_versions(res['config']['versions'])}.",
        "",
        markdown_table(res["controllers"]).rstrip(),
        "",
        "Training (raw: recorded transitions; augmented: local-frame samples the model is fitted on):",
        "",
        "| model | raw samples | augmented samples | training time (s) | from cache |",
        "|---|---|---|---|---|",
    ]
    for name, info in training.items():
        if name == "data":
            continue
        lines.append(
            f"| {name} | {info.get('raw_samples', '-')} | {info.get('augmented_samples', '-')} | "
            f"{info.get('fit_time_s', 0.0):.2f} | {info.get('cached', '-')} |"
        )
    data = training.get("data")
    if data:
        lines += ["", f"On-track data: {data['laps']} LMPC laps, {data['raw_samples']} transitions."]
    for sub in sorted(demo.glob("sensors-*/results.json")):
        other = _load(sub)
        lines += [
            "",
            f"The same comparison through the `{sub.parent.name.removeprefix('sensors-')}` sensors "
            f"(`{sub.parent.name}/` beside the demo's results; every controller behind the state estimator, "
            "the models learned from its smoothed states of the LMPC's laps):",
            "",
            markdown_table(other["controllers"]).rstrip(),
        ]
    lines += [
        "",
        f"![paths and errors]({_figure(demo / 'plot.png', fig_dir, 'demo_plot.png', doc)})",
        "",
        f"![step times]({_figure(demo / 'solve_times.png', fig_dir, 'demo_solve_times.png', doc)})",
        "",
    ]
    return lines


def faults_section(faults: Path, fig_dir: Path, doc: Path) -> list[str]:
    """One table per fault from ``rkmpc compare --fault NAME`` outputs in sub-folders."""
    lines = ["## Faults on the built-in track (`rkmpc compare --fault NAME`)", ""]
    for sub in sorted(p for p in faults.iterdir() if (p / "results.json").is_file()):
        res = _load(sub / "results.json")
        name = res["fault"]
        runs = [r for r in res["config"]["runs"] if r.get("fault")]
        params = runs[0]["fault"]["parameters"] if runs else {}
        lines += [
            f"### {name}: {json.dumps(params)}",
            "",
            fault_table(res["controllers"], res["faulted"], res["fault_effect"], name).rstrip(),
            "",
        ]
        for other_file in sorted(sub.glob("sensors-*/results.json")):
            other = _load(other_file)
            profile = other_file.parent.name.removeprefix("sensors-")
            lines += [
                f"Through the `{profile}` sensors:",
                "",
                fault_table(other["controllers"], other["faulted"], other["fault_effect"], name).rstrip(),
                "",
            ]
        if (sub / "plot_fault.png").is_file():
            fig = _figure(sub / "plot_fault.png", fig_dir, f"fault_{name}.png", doc)
            lines += [f"![{name}]({fig})", ""]
    return lines


def _study_table(folder: Path, stem: str) -> str:
    """The Markdown ``rkmpc study`` wrote beside ``STEM.json`` (the result's own tables)."""
    _load(folder / f"{stem}.json")  # the result it was written with must be there and readable
    return (folder / f"{stem}.md").read_text()


def tracks_section(tracks: Path) -> list[str]:
    """Summary and per-track rows of ``rkmpc study tracks``."""
    return [
        "## Every controller on every track (`make study-tracks`)",
        "",
        "Summary cells: mean ± standard deviation [min, max] over the completed laps; changes are "
        "against the LMPC on the same track and seed. Step times in this table come from parallel "
        "runs (two jobs on two cores) and are noisy; the benchmark below measures them alone.",
        "",
        _study_table(tracks, "study_tracks").rstrip(),
        "",
    ]


def data_section(data: Path, fig_dir: Path, doc: Path) -> list[str]:
    """The data-volume study."""
    table = _study_table(data, "study_data")
    fig = _figure(data / "study_data.png", fig_dir, "study_data.png", doc)
    return [
        "## Training data volume: RKMPC against KMPC (`make study-data`)",
        "",
        table.rstrip(),
        "",
        f"![data volume]({fig})",
        "",
    ]


def bench_section(bench: Path) -> list[str]:
    """The step-time benchmark beside the paper's Matlab times."""
    res = _load(bench)
    lines = [
        "## Step time (`make bench`)",
        "",
        f"One lap of {res['track']} per controller, measured alone, numerical libraries on one thread; "
        f"versions: {_versions(res['versions'])}.",
        "",
        "| controller | steps | median (ms) | mean (ms) | p99 (ms) | max (ms) | paper mean / max (ms) |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, s in res["controllers"].items():
        paper = PAPER_MS.get(label.split(" ")[0])
        ref = f"{paper[0]:.2f} / {paper[1]:.2f}" if paper else "-"
        lines.append(
            f"| {label} | {s['steps']} | {s['median_ms']:.3f} | {s['mean_ms']:.3f} | "
            f"{s['p99_ms']:.3f} | {s['max_ms']:.3f} | {ref} |"
        )
    return [*lines, ""]


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--demo", type=Path, default=Path("runs/demo"))
    parser.add_argument("--faults", type=Path, default=Path("runs/faults"))
    parser.add_argument("--tracks", type=Path, default=Path("runs/study-tracks"))
    parser.add_argument("--data", type=Path, default=Path("runs/study-data"))
    parser.add_argument("--bench", type=Path, default=Path("runs/bench/step_times.json"))
    parser.add_argument("--notes", type=Path, default=None, help="hand-written discussion placed first")
    parser.add_argument("--out", type=Path, default=Path("docs/results.md"))
    args = parser.parse_args()
    doc: Path = args.out
    fig_dir = doc.parent / "results"
    lines = [
        "# Results",
        "",
        "Made by `make results` from the files under `runs/`; do not edit the tables by hand.",
        "f1tenth plant (dynamic single-track, Pacejka tyres, servo lag), 50 ms control period; "
        "shared tracks at scale 0.1.",
        "",
    ]
    if args.notes is not None:
        lines += [args.notes.read_text().rstrip(), ""]
    if (args.demo / "results.json").is_file():
        lines += demo_section(args.demo, fig_dir, doc)
    if (args.tracks / "study_tracks.json").is_file():
        lines += tracks_section(args.tracks)
    if (args.data / "study_data.json").is_file():
        lines += data_section(args.data, fig_dir, doc)
    if args.faults.is_dir():
        lines += faults_section(args.faults, fig_dir, doc)
    if args.bench.is_file():
        lines += bench_section(args.bench)
    doc.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(doc, "\n".join(lines).rstrip() + "\n")
    print(f"wrote {doc}")


if __name__ == "__main__":
    main()
