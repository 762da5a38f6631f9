"""``rkmpc run`` and ``rkmpc compare``: drive controllers on a track and write the results."""

from __future__ import annotations

import argparse
from typing import Any

from rkmpc.cli.common import car_config, split_controllers

__all__ = ["cmd_compare", "model_files"]


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


def cmd_compare(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.analysis.tables import fault_table, rich_tables_fitting
    from rkmpc.core.io import output_folder
    from rkmpc.experiments.compare import CompareConfig, compare
    from rkmpc.experiments.report import title_of, write_comparison, write_single_run

    car = car_config(args)
    single = args.command == "run"
    names = [args.controller] if single else split_controllers(args.controllers)
    config = CompareConfig(
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
    track = config.scenario().track  # a bad track, scale or car is refused before any folder is made
    markers = ("metrics.json",) if single else ("results.json",)
    console = Console(stderr=True)
    logs: dict[str, Any] = {}
    with output_folder(args.out, force=args.force, markers=markers) as out:

        def on_run(label: str, result: Any) -> None:
            result.log.to_csv(out / ("log.csv" if single and "+" not in label else f"log_{label}.csv"))
            console.print(f"  {label}: {result.outcome}, {len(result.log)} steps")

        with console.status("starting", spinner="dots") as status:

            def say(message: str) -> None:
                status.update(message)
                console.print(message, soft_wrap=True)

            result = compare(config, logs=logs, on_run=on_run, say=say)
        (write_single_run if single else write_comparison)(out, result, logs, track)
    wide = Console(width=None if Console().is_terminal else 260)
    for table in rich_tables_fitting(result.metrics(), title_of(result), wide.width):
        wide.print(table)
    console.print(f"results in {args.out}/")
    if result.fault is not None:
        faulted = {name: run.metrics for name, run in result.fault.runs.items()}
        wide.print(fault_table(result.metrics(), faulted, result.fault.effects, result.fault.fault))
    return 0
