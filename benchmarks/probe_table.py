"""Replay issue 13's probe and print its table of cases and outcomes (markdown).

Run: ``python benchmarks/probe_table.py [--out runs/probe/table.md]``. The cases are the ones of
``tests/probe/test_probe.py`` (the table in ``tests/probe/probe_cases.py``): each is run here
without pytest, in a temporary folder, and its outcome is ``pass`` (it ended as its row expects),
``xfail`` (a known, reported failure) or ``fail``. Exits 1 when any case fails or an expected
failure passes.
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

from probe_cases import Case, Probe, all_cases

EXCERPT = 70


def _excerpt(text: str) -> str:
    text = " ".join(text.split()).replace("|", "\\|")
    return text if len(text) <= EXCERPT else text[: EXCERPT - 1] + "…"


def run_case(c: Case, folder: Path) -> tuple[str, str, float]:
    """``(outcome, message, seconds)`` of one case, run in its own folder."""
    folder.mkdir()
    start = time.perf_counter()
    try:
        evidence = c.run(Probe(folder))
    except Exception as exc:  # a failed case is a row of the table, not the end of it
        message = f"{type(exc).__name__}: {exc}"
        return ("xfail" if c.xfail else "fail"), (c.xfail or message), time.perf_counter() - start
    seconds = time.perf_counter() - start
    message = evidence.message.replace(f"{folder}/", "").replace(str(folder), "<folder>")
    evidence = replace(evidence, message=message)
    if c.xfail:
        return "fail (xpass)", evidence.message, seconds
    if evidence.outcome != c.expected:
        return "fail", f"ended as {evidence.outcome}: {evidence.message}", seconds
    return "pass", evidence.message, seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write the table to this file")
    parser.add_argument("-k", default="", help="only the cases whose id contains this text")
    args = parser.parse_args()
    cases = [c for c in all_cases() if args.k in c.id]
    rows = ["| id | case | expected | outcome | message |", "|---|---|---|---|---|"]
    counts: dict[str, int] = {}
    total = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rkmpc-probe-") as tmp:
        os.environ.setdefault("RKMPC_CACHE_DIR", str(Path(tmp) / "model-cache"))
        for i, c in enumerate(cases):
            outcome, message, seconds = run_case(c, Path(tmp) / f"case{i:03d}")
            counts[outcome] = counts.get(outcome, 0) + 1
            rows.append(f"| `{c.id}` | {c.description} | {c.expected} | {outcome} | {_excerpt(message)} |")
            print(f"{outcome:5s} {seconds:6.2f} s  {c.id}", file=sys.stderr)
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    text = "\n".join(rows) + f"\n\n{len(cases)} cases: {summary} ({time.perf_counter() - total:.0f} s)\n"
    print(text, end="")
    if args.out is not None:
        from rkmpc.core.io import write_text_atomic

        write_text_atomic(args.out, text)
    return 0 if set(counts) <= {"pass", "xfail"} else 1


if __name__ == "__main__":
    sys.exit(main())
