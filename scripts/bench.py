"""Benchmark (issue "Speed"): every performance target measured in one run, printed as one table.

    python scripts/bench.py [--quick] [--json FILE] [--only GROUP ...]

Groups, one module each under scripts/perf/:
  roundtrip   for reference, no target: round trips (`--timing fast`, pyserial host) against a PTY
              floor that answers without parsing, visits alternating; the floor inside an asyncio
              loop; each exchange's cost in process (model alone, model + runner). The regression
              guard of round trips is the Python call counts per exchange that `make test` holds
              (tests/unit/test_call_budget.py)
  throughput  64 busy ports of one daemon (MS2000 `W X`, MP-285 `c`): together ≥ 0.9 × one busy port
  idle        256 idle ports: daemon CPU 0 % (bound 1 %), RSS < 60 MB
  timing      `--timing realistic` at 9600 baud: reply bytes within 1 ms (p99) of the wire model,
              move completions within 1 % + 2 ms of the motion model
  timescale   `--time-scale 100`: a 10 s MS2000 move in ≤ 110 ms, landing where it would at scale 1
  startup     `stage-emu --version` and `ctl list` ≤ 0.15 s, `serve --profile ms2000` ready ≤ 0.3 s,
              the default rig ready ≤ 0.4 s (medians, PYTHONDONTWRITEBYTECODE=1)

Ratios compare figures of the same run, so they hold across machines; absolute times (start-up)
do not.
Exit status: 0 every target met, 1 a target missed (listed under the table), 2 a measurement could
not be made (a wrong reply, a timeout, a daemon that did not start).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scripts.perf import roundtrip, startup, throughput, timescale, timing  # noqa: E402
from scripts.perf.common import BenchError, Result, figure  # noqa: E402


@dataclass(frozen=True)
class Plan:
    """How much of each measurement a run does."""

    visits: int
    samples: int
    move_samples: int
    busy_window_s: float
    busy_visits: int
    idle_window_s: float
    timing_requests: int
    timing_moves: int
    startup_runs: int
    busy_ports: int = 64
    idle_ports: int = 256
    time_scale: float = 100.0
    scaled_move_s: float = 10.0


FULL = Plan(
    visits=15,
    samples=400,
    move_samples=60,
    busy_window_s=2.0,
    busy_visits=3,
    idle_window_s=10.0,
    timing_requests=1000,
    timing_moves=3,
    startup_runs=15,
)
QUICK = Plan(
    visits=5,
    samples=100,
    move_samples=20,
    busy_window_s=0.3,
    busy_visits=1,
    idle_window_s=2.0,
    timing_requests=200,
    timing_moves=1,
    startup_runs=5,
)

GROUPS: dict[str, Callable[[Path, Plan], list[Result]]] = {
    "roundtrip": lambda work, plan: roundtrip.run(work, plan.visits, plan.samples, plan.move_samples),
    "throughput": lambda work, plan: [
        throughput.busy(work / family, family, plan.busy_ports, plan.busy_window_s, plan.busy_visits)
        for family in ("ms2000", "mp285")
    ],
    "idle": lambda work, plan: throughput.idle(work, plan.idle_ports, plan.idle_window_s),
    "timing": lambda work, plan: timing.run(work, plan.timing_requests, plan.timing_moves),
    "timescale": lambda work, plan: [timescale.run(work, plan.time_scale, plan.scaled_move_s)],
    "startup": lambda work, plan: startup.run(work, plan.startup_runs),
}


REFERENCES = (
    "the no-parsing floor (round trips), one busy port (throughput), the motion model (moves), "
    "duration / scale (time scale), the interpreter's own start, `python -c pass` (start-up)"
)
#: why the round-trip rows carry no target (README, Performance)
NOTES = (
    "round trips are references, not targets: a model that follows the controllers' rules, in "
    "CPython, cannot come within 10 % of a loop that answers without parsing; their regression guard "
    "is the Python call counts per exchange that `make test` holds (tests/unit/test_call_budget.py)"
)


def table(results: list[Result]) -> str:
    """A Markdown table, padded to be read in a terminal too."""
    rows = [("case", "unit", "emulator p50/p99", "floor/ref p50/p99", "figure", "target", "result")]
    for result in results:
        rows.append(
            (
                result.case,
                result.unit,
                "/".join(figure(value) for value in result.emulator),
                "/".join(figure(value) for value in result.reference) or "—",
                ", ".join(
                    [f"{check.name} {figure(check.value)}" for check in result.checks]
                    + [f"{name} {figure(value)}" for name, value in result.info]
                ),
                ", ".join(f"{check.op} {figure(check.bound)}" for check in result.checks) or "—",
                ("pass" if result.passed else "FAIL") if result.checks else "info",
            )
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = [
        "| " + " | ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)) + " |"
        for row in rows
    ]
    lines.insert(1, "| " + " | ".join("-" * width for width in widths) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n", 2)[2],
    )
    parser.add_argument("--quick", action="store_true", help="10-15 s: fewer round trips, shorter windows")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the results here")
    parser.add_argument(
        "--only", nargs="+", choices=list(GROUPS), metavar="GROUP", help="run only these groups"
    )
    args = parser.parse_args()
    plan = QUICK if args.quick else FULL
    started = time.monotonic()
    results: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="stage-emu-bench-") as tmp:
        for name, measure in GROUPS.items():
            if args.only and name not in args.only:
                continue
            print(f"bench: {name}...", end="", file=sys.stderr, flush=True)
            begun = time.monotonic()
            # a measurement that cannot be made is not a missed target: exit 2, no table
            try:
                results += measure(Path(tmp) / name, plan)
                print(f" {time.monotonic() - begun:.1f} s", file=sys.stderr)
            except BenchError as error:
                print(f"\nbench: {name}: measurement failed: {error}", file=sys.stderr)
                return 2
            except Exception:
                print(file=sys.stderr)
                traceback.print_exc()
                print(f"bench: {name}: measurement failed (above)", file=sys.stderr)
                return 2
    print(table(results))
    print(f"\nfloor/ref: {REFERENCES}")
    if any(result.case.startswith("round trip") for result in results):
        print(f"note: {NOTES}")
    failures = [failure for result in results for failure in result.failures()]
    print(
        f"{'quick' if args.quick else 'full'} run, {time.monotonic() - started:.0f} s, "
        f"{os.cpu_count()} CPUs, load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}"
    )
    if args.json:
        report = {
            "quick": args.quick,
            "cpus": os.cpu_count(),
            "load_average": os.getloadavg(),
            "results": [result.as_json() for result in results],
            "missed": failures,
        }
        args.json.write_text(json.dumps(report, indent=1, ensure_ascii=False) + "\n")
    if failures:
        print("missed targets:\n  " + "\n  ".join(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
