"""``rkmpc study tracks | cars | data | pace``: the multi-run studies."""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rkmpc.cli.common import (
    CACHE_HELP,
    CONTROLLERS_HELP,
    SCALE_HELP,
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
    from rkmpc.experiments.studies.tracks import TracksStudyConfig
    from rkmpc.experiments.study import Study

__all__ = [
    "STUDIES",
    "StudyProgress",
    "add_study_parser",
    "cmd_study",
    "data_study_config",
    "pace_study_config",
    "run_study_command",
    "tracks_config",
]


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
    tracks.add_argument("--controllers", default=",".join(ALL_CONTROLLERS), help=CONTROLLERS_HELP)
    tracks.add_argument("--seeds", default="0", help="comma-separated seeds; one job per track and seed")
    tracks.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
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
    cars = kinds.add_parser(
        "cars",
        help="every controller on cars of the zoo it was not built for, with a real car's sensors "
        f"(--sensors, default {CARS_SENSORS})",
    )
    cars.add_argument("--cars", default=",".join(DEFAULT_CARS), help="zoo variants (or random-<seed>)")
    cars.add_argument("--tracks", default="builtin", help="as for `study tracks`")
    cars.add_argument("--controllers", default=",".join(CARS_CONTROLLERS), help=CONTROLLERS_HELP)
    cars.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
    cars.add_argument("--seeds", default="0", help="comma-separated seeds; one job per car, track and seed")
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
    data.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    data.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
    add_config_args(data)  # the seeds are --seeds, the data sizes --sizes
    data.add_argument("--sizes", default=",".join(str(n) for n in DEFAULT_SIZES), help="training samples")
    data.add_argument("--seeds", default="0,1,2", help="comma-separated seeds; one job per size and seed")
    data.add_argument("--controllers", default="rkmpc,kmpc", help=CONTROLLERS_HELP)
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
    pace.add_argument(
        "--controllers",
        default=",".join(PACE_CONTROLLERS),
        help=f"{CONTROLLERS_HELP} (default: {','.join(PACE_CONTROLLERS)}; nmpc-dynamic's climb takes "
        "6-15 minutes per real track, a few on the built-in one: leave it out for a quick look)",
    )
    pace.add_argument("--seed", type=at_least(0), default=None, help="else the --config file's (default: 0)")
    pace.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
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


class StudyProgress:
    """Prints one line per finished job (with how many warnings it raised), and a summary of the
    warnings at the end; the messages themselves are in the study's JSON (``warnings``)."""

    def __init__(self, console: Any) -> None:
        self.console = console
        self.warned: dict[str, tuple[str, ...]] = {}

    def __call__(self, outcome: Any, done: int, total: int) -> None:
        state = f"{outcome.seconds:.0f} s" if outcome.ok else f"FAILED: {outcome.error}"
        if outcome.resumed:
            state += " (earlier run, from the journal)"
        if outcome.warnings:
            self.warned[outcome.name] = outcome.warnings
            state += f", {len(outcome.warnings)} warning{'s' if len(outcome.warnings) > 1 else ''}"
        self.console.print(f"[{done}/{total}] {outcome.name}: {state}")

    def summary(self, json_file: Path) -> str | None:
        """One line counting the jobs' warnings by type, or None when no job warned."""
        if not self.warned:
            return None
        kinds = Counter(m.split(":", 1)[0] for messages in self.warned.values() for m in messages)
        counted = ", ".join(f"{kind} x{n}" for kind, n in kinds.most_common())
        return f"{len(self.warned)} jobs warned ({counted}); every message is under 'warnings' in {json_file}"


def _cache_dir(args: argparse.Namespace) -> str | None:
    return None if args.cache_dir is None else str(args.cache_dir)


def tracks_config(args: argparse.Namespace) -> TracksStudyConfig:
    """The tracks study's settings: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.common import expand_tracks
    from rkmpc.experiments.studies.tracks import TracksStudyConfig

    names = split_controllers(args.controllers)
    return TracksStudyConfig(
        tracks=expand_tracks(args.tracks.split(",")),
        car=car_config(args),
        controllers=names,
        seeds=ints(args.seeds, "--seeds"),
        scale=args.scale,
        baseline="lmpc" if "lmpc" in names else None,
        fault=getattr(args, "fault", None),
        cache_dir=_cache_dir(args),
    )


def _tracks(args: argparse.Namespace) -> Study[Any]:
    from rkmpc.experiments.studies.tracks import TracksStudy

    return TracksStudy(tracks_config(args))


#: The sensors of ``study cars`` unless ``--sensors`` (or a car file's ``[sensors]``) says otherwise:
#: the study speaks for real cars.
CARS_SENSORS = "f1tenth-real"


def _cars(args: argparse.Namespace) -> Study[Any]:
    from rkmpc.experiments.studies.cars import CarsStudy, CarsStudyConfig

    tracks = tracks_config(args)
    if args.sensors is None and tracks.car.sensors.is_ideal:
        tracks = replace(tracks, car=tracks.car.with_sensors(CARS_SENSORS))
    return CarsStudy(CarsStudyConfig(cars=args.cars.split(","), tracks=tracks))


def pace_study_config(args: argparse.Namespace) -> PaceStudyConfig:
    """The settings of ``study pace``: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.common import expand_tracks
    from rkmpc.experiments.studies.pace_job import PaceStudyConfig

    car = car_config(args)
    return PaceStudyConfig(
        tracks=expand_tracks(args.tracks.split(",")),
        car=car,
        controllers=tuple(split_controllers(args.controllers)),
        paces=ladder_from_args(args, car),
        scale=args.scale,
        cache_dir=_cache_dir(args),
    )


def _pace(args: argparse.Namespace) -> Study[Any]:
    from rkmpc.experiments.studies.pace import PaceStudy

    return PaceStudy(pace_study_config(args))


def data_study_config(args: argparse.Namespace) -> DataStudyConfig:
    """The settings of ``study data``: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.data_job import DataStudyConfig

    return DataStudyConfig(
        track=args.track,
        car=car_config(args),  # the seeds are the study's (--seeds), the data sizes its own
        scale=args.scale,
        sizes=ints(args.sizes, "--sizes"),
        seeds=ints(args.seeds, "--seeds"),
        controllers=tuple(split_controllers(args.controllers)),
    )


def _data(args: argparse.Namespace) -> Study[Any]:
    from rkmpc.experiments.studies.data import DataStudy

    return DataStudy(data_study_config(args))


#: The studies by sub-command: each builds its :class:`~rkmpc.experiments.study.Study` from the options.
STUDIES: dict[str, Callable[[argparse.Namespace], Study[Any]]] = {
    "tracks": _tracks,
    "cars": _cars,
    "pace": _pace,
    "data": _data,
}


def run_study_command(args: argparse.Namespace, study: Study[Any], stem: str) -> int:
    """Run a study into ``--out``: ``STEM.json``, ``STEM.md``, ``STEM.png``; the table on stdout."""
    from rich.console import Console

    from rkmpc.analysis.plots import save_figure
    from rkmpc.core.io import (
        check_output_folder,
        claim_output,
        output_folder,
        write_json_atomic,
        write_text_atomic,
    )
    from rkmpc.experiments.parallel import limit_threads
    from rkmpc.experiments.study import Parallel, run_study

    markers = (f"{stem}.json",)
    # The folder is claimed and checked before hours of runs (a second study into it is refused at
    # once), and made when they are done.
    with claim_output(args.out):
        check_output_folder(args.out, force=args.force, markers=markers)
        parallel = Parallel(n_jobs=args.jobs, backend=args.backend, address=args.address)
        limit_threads()  # this process trains too (the shared models, or jobs when --jobs 1)
        console = Console(stderr=True)
        journal = getattr(args, "journal", None)
        progress = StudyProgress(console)
        result = run_study(study, parallel=parallel, journal=journal, progress=progress, say=console.print)
        text = result.to_markdown()
        with output_folder(args.out, force=args.force, markers=markers) as out:
            write_json_atomic(out / f"{stem}.json", result.to_json())
            write_text_atomic(out / f"{stem}.md", text)
    print(text)
    warned = progress.summary(args.out / f"{stem}.json")
    if warned is not None:
        console.print(warned)
    # The figure last, into the finished folder: a figure that fails must not lose hours of runs.
    figure = result.figure()
    if figure is not None:
        save_figure(figure, args.out / f"{stem}.png")
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    return run_study_command(args, STUDIES[args.study](args), f"study_{args.study}")
