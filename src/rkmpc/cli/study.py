"""``rkmpc study tracks | cars | data | pace``: the multi-run studies."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rkmpc.cli.common import (
    CACHE_HELP,
    add_config_args,
    add_ladder_args,
    add_parallel_args,
    at_least,
    car_config,
    ints,
    ladder_from_args,
    split_controllers,
)

if TYPE_CHECKING:
    from rkmpc.experiments.studies.data_job import DataStudyConfig
    from rkmpc.experiments.studies.pace_job import PaceStudyConfig

__all__ = ["add_study_parser", "cmd_study", "data_study_config", "pace_study_config"]


JOURNAL_HELP = (
    "keep every finished job in this folder; a later run given it runs only the others "
    "(same settings and versions; more tracks or controllers are fine for `study pace`)"
)


def add_study_parser(sub: Any) -> None:
    from rkmpc.experiments.compare import ALL_CONTROLLERS
    from rkmpc.experiments.studies.cars import CARS_CONTROLLERS, DEFAULT_CARS
    from rkmpc.experiments.studies.data import DEFAULT_SIZES
    from rkmpc.experiments.studies.pace_job import PACE_CONTROLLERS

    study = sub.add_parser("study", help="multi-run studies: over tracks, cars, or training-data volume")
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
    add_config_args(tracks)
    tracks.add_argument(
        "--kmpc-samples", type=at_least(1000), default=None, help="else the --config file's (default: 50000)"
    )
    tracks.add_argument("--fault", default=None, help="also drive every controller with this fault")
    tracks.add_argument(
        "--epochs", type=at_least(1), default=None, help="training epochs of the learned models"
    )
    tracks.add_argument("--cache-dir", type=Path, default=None, help=CACHE_HELP)
    add_parallel_args(tracks)
    tracks.add_argument("--journal", type=Path, default=None, help=JOURNAL_HELP)
    cars = kinds.add_parser("cars", help="every controller on cars of the zoo it was not built for")
    cars.add_argument("--cars", default=",".join(DEFAULT_CARS), help="zoo variants (or random-<seed>)")
    cars.add_argument("--tracks", default="builtin", help="as for `study tracks`")
    cars.add_argument("--controllers", default=",".join(CARS_CONTROLLERS))
    cars.add_argument("--seeds", default="0")
    add_config_args(cars)
    cars.add_argument(
        "--kmpc-samples", type=at_least(1000), default=None, help="else the --config file's (default: 50000)"
    )
    cars.add_argument(
        "--epochs", type=at_least(1), default=None, help="training epochs of the learned models"
    )
    cars.add_argument("--cache-dir", type=Path, default=None, help=CACHE_HELP)
    add_parallel_args(cars)
    cars.add_argument("--journal", type=Path, default=None, help=JOURNAL_HELP)
    data = kinds.add_parser("data", help="RKMPC against KMPC as the number of training samples grows")
    data.add_argument("--track", default="builtin")
    data.add_argument("--scale", type=float, default=None)
    add_config_args(data)  # the seeds are --seeds, the data sizes --sizes
    data.add_argument("--sizes", default=",".join(str(n) for n in DEFAULT_SIZES), help="training samples")
    data.add_argument("--seeds", default="0,1,2")
    data.add_argument("--controllers", default="rkmpc,kmpc")
    data.add_argument(
        "--epochs",
        type=at_least(1),
        default=None,
        help="training epochs; else the --config file's (default: the models' own)",
    )
    add_parallel_args(data)
    pace = kinds.add_parser(
        "pace", help="raise each controller's pace up a ladder until its lap is no longer clean"
    )
    pace.add_argument("--tracks", default="builtin", help="as for `study tracks`")
    pace.add_argument("--controllers", default=",".join(PACE_CONTROLLERS))
    pace.add_argument("--seed", type=at_least(0), default=None, help="else the --config file's (default: 0)")
    pace.add_argument("--scale", type=float, default=None)
    add_config_args(pace, pace=False)  # the pace is the ladder's, from the car's own
    add_ladder_args(pace)
    pace.add_argument(
        "--data-laps",
        type=at_least(1),
        default=None,
        help="laps of data learned from at each pace; else the --config file's (default: 2)",
    )
    pace.add_argument(
        "--kmpc-samples", type=at_least(1000), default=None, help="else the --config file's (default: 50000)"
    )
    pace.add_argument(
        "--epochs",
        type=at_least(1),
        default=None,
        help="training epochs of the learned models; else the --config file's",
    )
    pace.add_argument("--cache-dir", type=Path, default=None, help=CACHE_HELP)
    add_parallel_args(pace)
    pace.add_argument("--journal", type=Path, default=None, help=JOURNAL_HELP)


def _study_progress(console: Any) -> Any:
    def progress(outcome: Any, done: int, total: int) -> None:
        state = f"{outcome.seconds:.0f} s" if outcome.ok else f"FAILED: {outcome.error}"
        if outcome.resumed:
            state += " (earlier run, from the journal)"
        console.print(f"[{done}/{total}] {outcome.name}: {state}")

    return progress


def pace_study_config(args: argparse.Namespace) -> PaceStudyConfig:
    """The settings of ``study pace``: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.common import expand_tracks
    from rkmpc.experiments.studies.pace_job import PaceStudyConfig

    car = car_config(args)
    return PaceStudyConfig(
        tracks=expand_tracks(args.tracks.split(",")),
        controllers=tuple(split_controllers(args.controllers)),
        paces=ladder_from_args(args, car),
        seed=car.training.seed,
        scale=args.scale,
        vehicle=car.preset,
        laps=car.training.data_laps,
        epochs=car.training.epochs,
        kmpc_samples=car.training.kmpc_samples,
        cache_dir=None if args.cache_dir is None else str(args.cache_dir),
        car_config=car,
    )


def data_study_config(args: argparse.Namespace) -> DataStudyConfig:
    """The settings of ``study data``: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.data_job import DataStudyConfig

    car = car_config(args)  # the seeds are the study's (--seeds), the data sizes its own
    return DataStudyConfig(
        track=args.track,
        scale=args.scale,
        vehicle=car.preset,
        sizes=ints(args.sizes, "--sizes"),
        seeds=ints(args.seeds, "--seeds"),
        controllers=tuple(split_controllers(args.controllers)),
        epochs=car.training.epochs,
        car_config=car,
    )


def cmd_study(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.analysis.plots import save_figure
    from rkmpc.analysis.study_plots import plot_cars_study, plot_data_study, plot_pace_study
    from rkmpc.core.io import check_output_folder, output_folder, write_json_atomic, write_text_atomic
    from rkmpc.experiments.journal import JobJournal
    from rkmpc.experiments.parallel import limit_threads
    from rkmpc.experiments.studies.cars import CarsStudyConfig, study_cars
    from rkmpc.experiments.studies.common import expand_tracks
    from rkmpc.experiments.studies.data import study_data
    from rkmpc.experiments.studies.pace import pace_journal_settings, study_pace
    from rkmpc.experiments.studies.tracks import TracksStudyConfig, study_tracks, track_journal_settings

    # The folder is checked before hours of runs, and made when they are done.
    check_output_folder(args.out, force=args.force, markers=(f"study_{args.study}.json",))
    journal = getattr(args, "journal", None)
    limit_threads()  # this process trains too (the KMPC model, or jobs when --jobs 1)
    console = Console(stderr=True)
    where = {"n_jobs": args.jobs, "backend": args.backend, "address": args.address}
    result: Any
    if args.study in ("tracks", "cars"):
        names = split_controllers(args.controllers)
        car = car_config(args)  # its seed is each job's
        options: dict[str, Any] = {
            "kmpc_samples": car.training.kmpc_samples,
            "epochs": car.training.epochs,
            "laps": car.training.data_laps,
            "limits": car.limits,
            "car_config": car,
        }
        if args.study == "tracks":
            options["fault"] = args.fault
            if car.car is not None:  # the cars study drives its own cars
                options["car"] = car.car
        if args.cache_dir is not None:
            options["cache_dir"] = str(args.cache_dir)
        config = TracksStudyConfig(
            tracks=expand_tracks(args.tracks.split(",")),
            controllers=names,
            seeds=ints(args.seeds, "--seeds"),
            scale=args.scale if args.study == "tracks" else None,
            vehicle=car.preset,
            baseline="lmpc" if "lmpc" in names else None,
            study_options=options,
        )
        kept = None if journal is None else JobJournal(journal, track_journal_settings(args.study)).open()
        if args.study == "tracks":
            result = study_tracks(
                config, **where, progress=_study_progress(console), say=console.print, journal=kept
            )
        else:
            cars_config = CarsStudyConfig(cars=args.cars, tracks=config)
            result = study_cars(
                cars_config, **where, progress=_study_progress(console), say=console.print, journal=kept
            )
    elif args.study == "pace":
        pace_config = pace_study_config(args)
        kept = None if journal is None else JobJournal(journal, pace_journal_settings(pace_config)).open()
        result = study_pace(pace_config, **where, progress=_study_progress(console), journal=kept)
    else:
        result = study_data(data_study_config(args), **where, progress=_study_progress(console))
    stem = f"study_{args.study}"
    text = result.to_markdown()
    with output_folder(args.out, force=args.force, markers=(f"{stem}.json",)) as out:
        write_json_atomic(out / f"{stem}.json", result.to_json())
        write_text_atomic(out / f"{stem}.md", text)
    print(text)
    # The figure last, into the finished folder: a figure that fails must not lose hours of runs.
    if args.study == "cars":
        save_figure(plot_cars_study(*result.plot_data()), args.out / "study_cars.png")
    elif args.study == "data":
        title = f"training data volume, {args.track}"
        figure = plot_data_study(result.series(), result.baseline.lateral_error_mean_m, title)
        save_figure(figure, args.out / "study_data.png")
    elif args.study == "pace":
        title = f"pace study, seed {result.config.seed}: clean laps up the pace ladder"
        save_figure(plot_pace_study(result.series(), title), args.out / "study_pace.png")
    return 0
