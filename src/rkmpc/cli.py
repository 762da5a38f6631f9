"""Command line: ``rkmpc run | compare | collect | train | tracks | study tracks | study data``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rkmpc.errors import RkmpcError


def _add_scenario_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    parser.add_argument(
        "--raceline", default=None, help="TUM race-line CSV to track instead of the centre line"
    )
    parser.add_argument(
        "--scale", type=float, default=None, help="scale of track files (default: 0.1 for f1tenth)"
    )
    parser.add_argument("--vehicle", default="f1tenth", choices=["f1tenth", "fullsize"])
    parser.add_argument("--laps", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice (noise)")
    parser.add_argument("--noise", action="store_true", help="add measurement noise to the observations")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="[NAME=]PATH",
        help="model file of a learned controller (rkmpc, rkmpc-paper, kmpc, lmpc-id); repeat as NAME=PATH",
    )


def _add_learning_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data-laps",
        type=int,
        default=2,
        help="LMPC laps of on-track data the learned controllers learn from",
    )
    parser.add_argument(
        "--kmpc-samples", type=int, default=50_000, help="random-excitation samples of the KMPC model"
    )
    parser.add_argument(
        "--fault",
        default=None,
        help="also drive every controller with this fault (noise, delay, friction, heavy); report the effect",
    )
    parser.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        help="trained-model cache (default: $RKMPC_CACHE_DIR, else ~/.cache/rkmpc)",
    )
    parser.add_argument("--no-cache", action="store_true", help="train every model afresh, store nothing")
    parser.add_argument("--epochs", type=int, default=None, help="training epochs of the learned models")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``rkmpc`` command."""
    from rkmpc.control.factory import CONTROLLERS
    from rkmpc.experiments.learned import ALL_CONTROLLERS

    parser = argparse.ArgumentParser(prog="rkmpc", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="drive one controller around a track")
    run.add_argument("--controller", required=True, choices=sorted(CONTROLLERS))
    _add_scenario_args(run)
    _add_learning_args(run)
    compare = sub.add_parser(
        "compare",
        help="learn on the track, drive several controllers and tabulate them (the paper's Table I)",
    )
    compare.add_argument(
        "--controllers", default=",".join(ALL_CONTROLLERS), help="comma-separated controller names"
    )
    _add_scenario_args(compare)
    _add_learning_args(compare)
    collect = sub.add_parser("collect", help="record on-track (or random-excitation) data")
    collect.add_argument("--controller", default="lmpc", choices=["pp", "lmpc"])
    collect.add_argument(
        "--excitation",
        type=int,
        default=0,
        metavar="N",
        help="instead: N random-excitation samples in open space (for KMPC)",
    )
    collect.add_argument(
        "--from-log",
        type=Path,
        default=None,
        metavar="LOG",
        help="instead: turn the log.csv of an earlier `rkmpc run` into a data set",
    )
    _add_scenario_args(collect)
    collect.set_defaults(laps=2)
    train = sub.add_parser("train", help="train a model from a data set")
    train.add_argument("--data", required=True, type=Path)
    train.add_argument("--kind", required=True, choices=["residual", "paper", "koopman", "identified"])
    train.add_argument("--vehicle", default="f1tenth", choices=["f1tenth", "fullsize"])
    train.add_argument("--epochs", type=int, default=None)
    train.add_argument("--seed", type=int, default=0)
    train.add_argument("--out", required=True, type=Path, help="model file")
    sub.add_parser("tracks", help="list the built-in tracks")
    _add_study_parser(sub)
    return parser


def _add_parallel_args(parser: argparse.ArgumentParser) -> None:
    import os

    parser.add_argument(
        "--jobs", type=int, default=os.cpu_count() or 1, help="parallel jobs (default: cores)"
    )
    parser.add_argument("--backend", default="loky", choices=["loky", "dask", "ray"], help="where jobs run")
    parser.add_argument("--address", default=None, help="scheduler address of a running dask or ray cluster")
    parser.add_argument("--out", required=True, type=Path, help="output folder")


def _add_study_parser(sub: Any) -> None:
    from rkmpc.experiments.learned import ALL_CONTROLLERS
    from rkmpc.experiments.studies import DEFAULT_SIZES

    study = sub.add_parser("study", help="multi-run studies: over tracks, or over training-data volume")
    kinds = study.add_subparsers(dest="study", required=True)
    tracks = kinds.add_parser(
        "tracks", help="every controller on many tracks; mean and spread per controller"
    )
    tracks.add_argument(
        "--tracks",
        default="builtin",
        help="comma-separated built-in names, centre-line CSV files or folders of them",
    )
    tracks.add_argument("--controllers", default=",".join(ALL_CONTROLLERS))
    tracks.add_argument("--seeds", default="0", help="comma-separated seeds; one job per track and seed")
    tracks.add_argument("--scale", type=float, default=None)
    tracks.add_argument("--vehicle", default="f1tenth", choices=["f1tenth", "fullsize"])
    tracks.add_argument("--kmpc-samples", type=int, default=50_000)
    tracks.add_argument("--fault", default=None, help="also drive every controller with this fault")
    tracks.add_argument("--epochs", type=int, default=None, help="training epochs of the learned models")
    tracks.add_argument("--cache-dir", type=Path, default=None)
    _add_parallel_args(tracks)
    data = kinds.add_parser("data", help="RKMPC against KMPC as the number of training samples grows")
    data.add_argument("--track", default="builtin")
    data.add_argument("--scale", type=float, default=None)
    data.add_argument("--vehicle", default="f1tenth", choices=["f1tenth", "fullsize"])
    data.add_argument("--sizes", default=",".join(str(n) for n in DEFAULT_SIZES), help="training samples")
    data.add_argument("--seeds", default="0,1,2")
    data.add_argument("--controllers", default="rkmpc,kmpc")
    data.add_argument("--epochs", type=int, default=None, help="training epochs (default: the models' own)")
    _add_parallel_args(data)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == "tracks":
            return _cmd_tracks()
        if args.command == "collect":
            return _cmd_collect(args)
        if args.command == "train":
            return _cmd_train(args)
        if args.command == "study":
            from rkmpc.experiments.parallel import limit_threads

            limit_threads()  # this process trains too (the KMPC model, or jobs when --jobs 1)
            return _cmd_study_tracks(args) if args.study == "tracks" else _cmd_study_data(args)
        names = [args.controller] if args.command == "run" else _split(args.controllers)
        return _cmd_compare(args, names, single=args.command == "run")
    except (RkmpcError, ValueError, OSError) as exc:
        print(f"rkmpc: error: {exc}", file=sys.stderr)
        return 2


def _split(text: str) -> list[str]:
    from rkmpc.control.factory import CONTROLLERS

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in CONTROLLERS]
    if unknown or not names:
        raise ValueError(f"unknown controller(s) {unknown}; known: {sorted(CONTROLLERS)}")
    return names


def _model_files(names: list[str], specs: list[str]) -> dict[str, str]:
    """Model files by controller, from ``--model [NAME=]PATH`` arguments."""
    from rkmpc.control.factory import MODEL_KIND

    paths: dict[str, str] = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep:
            learned = [n for n in names if n in MODEL_KIND]
            if len(learned) != 1:
                raise ValueError("--model PATH needs exactly one learned controller; use NAME=PATH")
            name, path = learned[0], spec
        if name not in names:
            raise ValueError(f"--model {name}=...: {name!r} is not among the controllers {names}")
        if name not in MODEL_KIND:
            raise ValueError(f"--model {name}=...: {name!r} takes no model; learned: {sorted(MODEL_KIND)}")
        paths[name] = path
    return paths


def _cmd_collect(args: argparse.Namespace) -> int:
    from rkmpc.experiments.runner import DEFAULT_NOISE
    from rkmpc.learning.collect import collect, collect_excitation
    from rkmpc.scenario import load_scenario

    if args.from_log is not None:
        from rkmpc.learning.dataset import TransitionDataset
        from rkmpc.sim.log import StepLog

        log = StepLog.from_csv(args.from_log)
        data = TransitionDataset.from_log(log, metadata={**log.metadata, "source": str(args.from_log)})
        data.save(args.out)
        print(f"{len(data)} transitions -> {args.out}")
        return 0
    scenario = load_scenario(args.track, raceline=args.raceline, scale=args.scale, vehicle=args.vehicle)
    noise = DEFAULT_NOISE if args.noise else None
    if args.excitation:
        data = collect_excitation(scenario, n_samples=args.excitation, seed=args.seed)
    else:
        data = collect(scenario, controller=args.controller, laps=args.laps, seed=args.seed, noise=noise)
    data.save(args.out)
    print(f"{len(data)} transitions -> {args.out}")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from rkmpc.learning.dataset import TransitionDataset
    from rkmpc.scenario import vehicle_preset

    data = TransitionDataset.load(args.data)
    wheelbase = vehicle_preset(args.vehicle).params().wheelbase
    if args.kind == "identified":
        from rkmpc.learning.identification import identify
        from rkmpc.learning.model_io import save_identified

        ident = identify(data, wheelbase)
        save_identified(ident, args.out, {"data_hash": data.content_hash(), "data_metadata": data.metadata})
        print(f"{ident} -> {args.out}")
        return 0
    from rkmpc.learning.augmentation import AugmentConfig
    from rkmpc.learning.pipeline import TrainConfig, default_model_options, train_model

    options = default_model_options(args.kind, seed=args.seed)
    if args.epochs is not None:
        options["epochs"] = args.epochs
    from rich.console import Console
    from rich.progress import Progress

    config = TrainConfig(kind=args.kind, augment=AugmentConfig(seed=args.seed), model=options)
    console = Console(stderr=True)
    with Progress(console=console, transient=True, disable=not console.is_terminal) as progress:
        task = progress.add_task(f"training {args.kind}", total=options.get("epochs", 300))

        def on_epoch(epoch: int, loss: float) -> None:
            progress.update(task, completed=epoch, description=f"training {args.kind} (loss {loss:.3g})")

        model, report = train_model(data, wheelbase, config, on_epoch=on_epoch)
    model.save(args.out, metadata=model.metadata_)
    print(
        f"{args.kind} model: {report.raw_count} raw -> {report.augmented_count} augmented samples, "
        f"{report.fit_time_s:.1f} s -> {args.out}"
    )
    err = report.multi_step_error
    if err:
        steps = [k for k in (1, 10, len(err)) if k <= len(err)]
        print("held-out prediction error: " + ", ".join(f"{err[k - 1]:.4f} at step {k}" for k in steps))
    return 0


def _cmd_tracks() -> int:
    from rkmpc.track.builtin import BUILTIN_DESCRIPTIONS, builtin_track

    for name, text in BUILTIN_DESCRIPTIONS.items():
        length = builtin_track(name).centerline.length
        print(f"{name:12s} {length:7.1f} m  {text}")
    return 0


def _cmd_compare(args: argparse.Namespace, names: list[str], *, single: bool) -> int:
    from rich.console import Console
    from rich.table import Table

    from rkmpc.analysis.plots import plot_runs, plot_solve_times, save_figure
    from rkmpc.analysis.table import fault_table, markdown_table, table_header, table_rows
    from rkmpc.experiments.learned import TrackStudy, evaluate_track
    from rkmpc.sim.log import StepLog, write_json_atomic

    console = Console(stderr=True)
    models = _model_files(names, args.model)
    study = TrackStudy(
        track=args.track,
        raceline=args.raceline,
        scale=args.scale,
        vehicle=args.vehicle,
        controllers=tuple(names),
        laps=args.data_laps,
        run_laps=args.laps,
        seed=args.seed,
        noise=args.noise,
        fault=args.fault,
        kmpc_samples=args.kmpc_samples,
        cache_dir=None if args.cache_dir is None else str(args.cache_dir),
        use_cache=not args.no_cache,
        model_files=tuple(models.items()),
        epochs=args.epochs,
    )
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    logs: dict[str, StepLog] = {}

    def on_run(label: str, result: Any) -> None:
        log_name = "log.csv" if single and "+" not in label else f"log_{label}.csv"
        result.log.to_csv(out / log_name)
        console.print(f"  {label}: {result.outcome}, {len(result.log)} steps")

    with console.status("starting", spinner="dots") as status:

        def say(message: str) -> None:
            status.update(message)
            console.print(message)

        report = evaluate_track(study, logs=logs, on_run=on_run, say=say)
    results = report["controllers"]
    if single:
        write_json_atomic(
            out / "metrics.json",
            {**results[names[0]], "training": report["training"], "config": report["config"]},
        )
    else:
        write_json_atomic(out / "results.json", report)
        text = markdown_table(results)
        if args.fault:
            text += "\n" + fault_table(results, report["faulted"], report["fault_effect"], args.fault)
        (out / "table.md").write_text(text)
    cfg = report["config"]["scenario"]
    title = f"{cfg['track']} (scale {cfg['scale']:g}, {cfg['vehicle']})"
    nominal = {k: v for k, v in logs.items() if "+" not in k}
    track = _scenario_track(study)
    save_figure(plot_runs(nominal, track, title=title), out / "plot.png")
    if not single:
        save_figure(plot_solve_times(nominal, period_s=cfg["dt"], title=title), out / "solve_times.png")
    if args.fault:
        faulted = {k: v for k, v in logs.items() if "+" in k}
        save_figure(plot_runs(faulted, track, title=f"{title}, fault: {args.fault}"), out / "plot_fault.png")

    with_change = "lmpc" in results and len(results) > 1
    table = Table(title=title)
    for col in table_header(with_change):
        table.add_column(col)
    for row in table_rows(results, "lmpc" if with_change else None):
        table.add_row(*row)
    wide = Console(width=None if Console().is_terminal else 260)
    wide.print(table)
    if args.fault:
        wide.print(fault_table(results, report["faulted"], report["fault_effect"], args.fault))
    return 0


def _scenario_track(study: Any) -> Any:
    from rkmpc.scenario import load_scenario

    return load_scenario(study.track, raceline=study.raceline, scale=study.scale, vehicle=study.vehicle).track


def _ints(text: str, what: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"{what} must be comma-separated integers, got {text!r}") from None


def _study_progress(console: Any) -> Any:
    def progress(outcome: Any, done: int, total: int) -> None:
        state = f"{outcome.seconds:.0f} s" if outcome.ok else f"FAILED: {outcome.error}"
        console.print(f"[{done}/{total}] {outcome.name}: {state}")

    return progress


def _cmd_study_tracks(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.experiments.studies import TracksStudyConfig, expand_tracks, study_tracks, tracks_markdown

    console = Console(stderr=True)
    names = _split(args.controllers)
    seeds = _ints(args.seeds, "--seeds")
    options: dict[str, Any] = {"kmpc_samples": args.kmpc_samples, "fault": args.fault, "epochs": args.epochs}
    if args.cache_dir is not None:
        options["cache_dir"] = str(args.cache_dir)
    config = TracksStudyConfig(
        tracks=expand_tracks(args.tracks.split(",")),
        controllers=names,
        seeds=seeds,
        scale=args.scale,
        vehicle=args.vehicle,
        baseline="lmpc" if "lmpc" in names else None,
        study_options=options,
    )
    if "kmpc" in names:
        # Train the KMPC model once here; the parallel jobs then read it from the cache.
        from rkmpc.experiments.cache import ModelCache
        from rkmpc.experiments.learned import train_kmpc
        from rkmpc.scenario import load_scenario

        scenario = load_scenario(config.tracks[0], scale=args.scale, vehicle=args.vehicle)
        for seed in seeds:
            console.print(f"KMPC model, seed {seed}: {args.kmpc_samples} random-excitation samples (cached)")
            train_kmpc(
                scenario,
                samples=args.kmpc_samples,
                seed=seed,
                cache=ModelCache(args.cache_dir),
                epochs=args.epochs,
            )
    console.print(f"{len(config.tracks)} tracks x {len(seeds)} seeds on {args.jobs} {args.backend} workers")
    result = study_tracks(
        config,
        n_jobs=args.jobs,
        backend=args.backend,
        address=args.address,
        progress=_study_progress(console),
    )
    print(_write_study(args.out, "study_tracks", result, tracks_markdown(result)))
    return 0


def _cmd_study_data(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.analysis.plots import save_figure
    from rkmpc.analysis.study_plots import plot_data_study
    from rkmpc.experiments.studies import DataStudyConfig, data_markdown, study_data

    console = Console(stderr=True)
    model_options = {} if args.epochs is None else {"epochs": args.epochs}
    config = DataStudyConfig(
        track=args.track,
        scale=args.scale,
        vehicle=args.vehicle,
        sizes=_ints(args.sizes, "--sizes"),
        seeds=_ints(args.seeds, "--seeds"),
        controllers=tuple(_split(args.controllers)),
        model_options=model_options,
    )
    result = study_data(
        config,
        n_jobs=args.jobs,
        backend=args.backend,
        address=args.address,
        progress=_study_progress(console),
    )
    out: Path = args.out
    text = _write_study(out, "study_data", result, data_markdown(result))
    save_figure(plot_data_study(result, title=f"training data volume, {args.track}"), out / "study_data.png")
    print(text)
    return 0


def _write_study(out: Path, stem: str, result: dict[str, Any], text: str) -> str:
    """Write ``<stem>.json`` and ``<stem>.md`` of a study into ``out``; returns the Markdown."""
    from rkmpc.sim.log import write_json_atomic

    write_json_atomic(out / f"{stem}.json", result)
    _write_text_atomic(out / f"{stem}.md", text)
    return text


def _write_text_atomic(path: Path, text: str) -> None:
    import os
    import tempfile

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
