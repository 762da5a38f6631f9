"""``rkmpc run`` and ``rkmpc compare``: drive controllers on a track and write the results."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rkmpc.cli.common import car_config, split_controllers

__all__ = ["FAILED", "GUARD_SHARE", "cmd_compare", "degraded", "model_files"]

#: File in ``OUT/sensors-PROFILE/`` that says why the comparison with those sensors failed.
FAILED = "failed.txt"


def model_files(names: list[str], specs: list[str]) -> dict[str, str]:
    """Model files by controller, from ``--model [NAME=]PATH`` arguments."""
    from rkmpc.learning.recipes import recipe_for

    learned = [n for n in names if recipe_for(n) is not None]
    paths: dict[str, str] = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep:
            if len(learned) != 1:
                raise ValueError("--model PATH needs exactly one learned controller; use NAME=PATH")
            name, path = learned[0], spec
        if name not in names:
            raise ValueError(f"--model {name}=...: {name!r} is not among the controllers {names}")
        if name not in learned:
            raise ValueError(f"--model {name}=...: {name!r} takes no model; learned: {learned}")
        paths[name] = path
    return paths


#: Share of a run's steps a learned controller may keep its baseline's command (``guard``) unsaid.
GUARD_SHARE = 0.02


def degraded(label: str, result: Any) -> str | None:
    """A line for the terminal when more than :data:`GUARD_SHARE` of a run's steps were ``guard`` steps."""
    counts = result.status_counts
    guard = counts["guard"] if "guard" in counts else 0
    steps = max(len(result.log), 1)
    if guard <= GUARD_SHARE * steps:
        return None
    return (
        f"  {label}: {guard} of {steps} steps ({guard / steps:.0%}) kept the baseline's command (guard): "
        "an input it needs was not measured or not finite"
    )


def cmd_compare(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.analysis.tables import fault_table, rich_tables_fitting
    from rkmpc.core.io import output_folder, write_text_atomic
    from rkmpc.experiments.report import lateral_limit_of, title_of

    car = car_config(args)
    single = args.command == "run"
    names = [args.controller] if single else split_controllers(args.controllers)
    profiles = [None]
    also = getattr(args, "also_sensors", None)
    if also is not None and also != "none" and also != car.sensors.name:
        profiles.append(also)
    console = Console(stderr=True)
    markers = ("metrics.json",) if single else ("results.json",)
    configs = [_config(args, car.with_sensors(profile), names) for profile in profiles]
    for config in configs:
        # A bad track, scale, car, profile or fault is refused before any folder is made.
        config.check_fault(config.scenario())
    failure: Exception | None = None
    with output_folder(args.out, force=args.force, markers=markers) as out:
        results = []
        for profile, config in zip(profiles, configs, strict=True):
            folder = out if profile is None else out / f"sensors-{profile}"
            folder.mkdir(exist_ok=True)
            if profile is not None:
                console.print(f"the same with the {profile} sensors (docs/sensors.md)")
            try:
                results.append(_drive(config, folder, single, console))
            except Exception as error:
                if profile is None:
                    raise
                # The first comparison is complete and kept; the error is raised once it is saved.
                failure = error
                write_text_atomic(folder / FAILED, f"{type(error).__name__}: {error}\n")
    wide = Console(width=None if Console().is_terminal else 100)
    for profile, result in zip(profiles, results, strict=False):
        title = title_of(result) + ("" if profile is None else f", {profile} sensors")
        limit = lateral_limit_of(result)
        for table in rich_tables_fitting(result.metrics(), title, wide.width, lateral_limit=limit):
            wide.print(table)
        if result.fault is not None:
            faulted = {name: run.metrics for name, run in result.fault.runs.items()}
            wide.print(fault_table(result.metrics(), faulted, result.fault.effects, result.fault.fault))
    if failure is not None:
        console.print(
            f"[red]the comparison with the {also} sensors failed; the one with the {car.sensors.name} "
            f"sensors is kept in {args.out}/ ({args.out}/sensors-{also}/{FAILED} says why)[/red]"
        )
        raise failure
    console.print(f"results in {args.out}/" + ("" if len(profiles) == 1 else f" (and sensors-{also}/)"))
    return 0


def _config(args: argparse.Namespace, car: Any, names: list[str]) -> Any:
    from rkmpc.experiments.compare import CompareConfig

    return CompareConfig(
        track=args.track,
        car=car,
        controllers=tuple(names),
        raceline=args.raceline,
        scale=args.scale,
        run_laps=args.laps,
        noise=args.noise,
        fault=args.fault,
        model_files=tuple(model_files(names, args.model).items()),
        allow_mismatch=args.allow_mismatch,
        cache_dir=None if args.cache_dir is None else str(args.cache_dir),
        use_cache=not args.no_cache,
    )


def _drive(config: Any, out: Path, single: bool, console: Any) -> Any:
    """One comparison into ``out``: its logs, results and plots; what it found."""
    from rkmpc.experiments.compare import compare
    from rkmpc.experiments.report import write_comparison, write_single_run

    logs: dict[str, Any] = {}

    def on_run(label: str, result: Any) -> None:
        result.log.to_csv(out / ("log.csv" if single and "+" not in label else f"log_{label}.csv"))
        why = f" ({result.failure})" if result.failure else ""
        console.print(f"  {label}: {result.outcome}, {len(result.log)} steps{why}")
        warning = degraded(label, result)
        if warning is not None:
            console.print(f"[yellow]{warning}[/yellow]")

    with console.status("starting", spinner="dots") as status:

        def say(message: str) -> None:
            status.update(message)
            console.print(message, soft_wrap=console.is_terminal)

        result = compare(config, logs=logs, on_run=on_run, say=say)
    (write_single_run if single else write_comparison)(out, result, logs, config.scenario().track)
    return result
