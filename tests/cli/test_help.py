"""Every option of every command says what it is (issue 27: --scale, --controllers, ... had no help,
so ``-h`` showed neither what they do nor their defaults)."""

from __future__ import annotations

import argparse
from collections.abc import Iterator

from rkmpc.cli import build_parser


def _options(parser: argparse.ArgumentParser, name: str) -> Iterator[tuple[str, argparse.Action]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, child in action.choices.items():
                yield from _options(child, f"{name} {sub}")
        elif action.option_strings:
            yield name, action


def test_every_option_of_every_command_has_help():
    options = list(_options(build_parser(), "rkmpc"))
    assert len(options) > 200
    missing = [f"{name} {action.option_strings[-1]}" for name, action in options if not action.help]
    assert missing == []


def test_the_help_gaps_of_the_probe_are_filled(capsys):
    import pytest

    for argv, needles in [
        (["study", "tracks"], ["--scale SCALE         scale of track files"]),
        (
            ["learn-pace"],
            ["--scale SCALE         scale of track files", "the learned controller that climbs"],
        ),
        (["study", "pace"], ["nmpc-dynamic's climb takes 6-15 minutes per real track"]),
        (["compare"], ["$XDG_CACHE_HOME/rkmpc"]),
        (["collect"], ["laps of data to record (default: 2)", "the controller that drives the laps"]),
    ]:
        with pytest.raises(SystemExit):
            build_parser().parse_args([*argv, "-h"])
        text = " ".join(capsys.readouterr().out.split())
        for needle in needles:
            assert " ".join(needle.split()) in text, (argv, needle)
