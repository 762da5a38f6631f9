"""Replay the probes (issues 13 and 27) and print their table of cases and outcomes (markdown).

Run: ``python benchmarks/probe_table.py [--out runs/probe/table.md] [--fast]``. The cases are the
ones of ``tests/probe/test_probe.py`` (the table in ``tests/probe/probe_cases.py``): each is run
here without pytest, in a temporary folder, and its outcome is ``pass`` (it ended as its row
expects), ``xfail`` (a known, reported failure) or ``fail``. Exits 1 when any case fails or an
expected failure passes.

A summary table follows, in the issue's terms: a case that passes counts as what it ended as (a
clear error, a graceful fall-back, a correct result); one that does not (failed, or a known
failure) as what its problem was when the probe found it (lost, hang, silent, traceback, unclear,
friction), a case that ran past its guard as a hang and one that raised something else than an
assertion as a traceback.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "probe"))

from probe_cases import OUTCOMES, PROBLEMS, Case, Hang, Probe, all_cases

EXCERPT = 70
#: The summary's columns: what a case that does not pass was, then what a passing one ended as.
SUMMARY = {
    "lost": "lost",
    "hang": "hangs",
    "silent": "silent",
    "traceback": "tracebacks",
    "unclear": "unclear",
    "friction": "friction",
    "clear_error": "clear errors",
    "graceful": "graceful",
    "correct": "correct",
}
assert set(SUMMARY) == {*PROBLEMS, *OUTCOMES}


def _excerpt(text: str) -> str:
    text = " ".join(text.split()).replace("|", "\\|")
    return text if len(text) <= EXCERPT else text[: EXCERPT - 1] + "…"


def run_case(c: Case, folder: Path) -> tuple[str, str, float, str]:
    """``(outcome, message, seconds, summary column)`` of one case, run in its own folder."""
    folder.mkdir()
    start = time.perf_counter()
    try:
        evidence = c.run(Probe(folder))
    except Exception as exc:  # a failed case is a row of the table, not the end of it
        message = f"{type(exc).__name__}: {exc}"
        kind = "hang" if isinstance(exc, Hang) else c.problem or "fail"
        if not isinstance(exc, AssertionError):
            kind = "traceback"
        return ("xfail" if c.xfail else "fail"), (c.xfail or message), time.perf_counter() - start, kind
    seconds = time.perf_counter() - start
    message = evidence.message.replace(f"{folder}/", "").replace(str(folder), "<folder>")
    evidence = replace(evidence, message=message)
    if c.xfail:
        return "fail (xpass)", evidence.message, seconds, evidence.outcome
    if evidence.outcome != c.expected:
        return "fail", f"ended as {evidence.outcome}: {evidence.message}", seconds, c.problem or "fail"
    return "pass", evidence.message, seconds, evidence.outcome


def summary_table(columns: dict[str, int]) -> str:
    """The counts in the issue's terms (see the module), as a markdown table."""
    names = [*SUMMARY.values(), *(["other failures"] if "fail" in columns else [])]
    counts = [str(columns.get(key, 0)) for key in SUMMARY] + (
        [str(columns["fail"])] if "fail" in columns else []
    )
    return "\n".join(
        ["| " + " | ".join(names) + " |", "|" + "---|" * len(names), "| " + " | ".join(counts) + " |"]
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write the table to this file")
    parser.add_argument("-k", default="", help="only the cases whose id contains this text")
    parser.add_argument("--fast", action="store_true", help="leave out the slow cases (the fast tier's)")
    args = parser.parse_args()
    cases = [c for c in all_cases() if args.k in c.id and not (args.fast and c.slow)]
    rows = ["| id | case | expected | outcome | message |", "|---|---|---|---|---|"]
    counts: dict[str, int] = {}
    columns: dict[str, int] = {}
    total = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rkmpc-probe-") as tmp:
        os.environ.setdefault("RKMPC_CACHE_DIR", str(Path(tmp) / "model-cache"))
        for i, c in enumerate(cases):
            outcome, message, seconds, column = run_case(c, Path(tmp) / f"case{i:03d}")
            counts[outcome] = counts.get(outcome, 0) + 1
            columns[column] = columns.get(column, 0) + 1
            rows.append(f"| `{c.id}` | {c.description} | {c.expected} | {outcome} | {_excerpt(message)} |")
            print(f"{outcome:5s} {seconds:6.2f} s  {c.id}", file=sys.stderr)
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    text = "\n".join(rows) + f"\n\n{len(cases)} cases: {summary} ({time.perf_counter() - total:.0f} s)\n"
    text += "\n" + summary_table(columns) + "\n"
    print(text, end="")
    if args.out is not None:
        from rkmpc.core.io import write_text_atomic

        write_text_atomic(args.out, text)
    return 0 if set(counts) <= {"pass", "xfail"} else 1


if __name__ == "__main__":
    sys.exit(main())
