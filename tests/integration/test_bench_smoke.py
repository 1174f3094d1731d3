"""The benchmark's measurements, end to end in miniature (`make bench` runs them at length).

Figures are not asserted: at this size and on a shared machine they are noise. What must hold on any
machine: every measurement completes (exact replies, no setup race with the floor), its figures are
finite, and the table renders one row per result.
"""

from __future__ import annotations

import math
from pathlib import Path

from scripts.bench import table
from scripts.perf import roundtrip, startup, throughput, timescale, timing
from scripts.perf.common import Result


def finite(results: list[Result]) -> None:
    for result in results:
        checked = [check.value for check in result.checks] + [value for _, value in result.info]
        figures = [*result.emulator, *result.reference, *checked]
        assert figures and all(math.isfinite(value) for value in figures), result


def test_round_trips_against_the_floor(tmp_path: Path) -> None:
    results = roundtrip.run(tmp_path, visits=2, samples=5, move_samples=2)
    cases = [f"round trip {case.name}" for case in roundtrip.CASES]
    fixed = [case for case in roundtrip.CASES if isinstance(case, roundtrip.Fixed)]
    in_process = [f"in process {case.name}: model alone" for case in fixed]
    assert [result.case for result in results] == [
        *cases,
        f"{cases[2]} answered in an asyncio loop",
        *in_process,
    ]
    # every row a reference, no target: the call-count ceilings of `make test` guard round trips
    assert all(not result.checks and len(result.info) == 2 for result in results)
    assert [name for name, _ in results[0].info] == ["p50 ratio", "p99 ratio"]
    finite(results)
    assert "FAIL" not in table(results)
    assert table(results).count("\n") == len(results) + 1


def test_busy_and_idle_ports(tmp_path: Path) -> None:
    busy = throughput.busy(tmp_path / "busy", "mp285", ports=2, window_s=0.1, visits=1)
    idle = throughput.idle(tmp_path / "idle", ports=4, window_s=0.1)
    finite([busy, *idle])
    assert busy.emulator[0] > 0 and busy.reference[0] > 0


def test_realistic_timing_and_time_scale(tmp_path: Path) -> None:
    timed = timing.run(tmp_path / "timing", requests=3, moves=1)
    scaled = timescale.run(tmp_path / "scale", scale=100, seconds=1.0)
    finite([*timed, scaled])
    assert scaled.checks[1].passed, scaled.details  # the same position as at scale 1: not a timing


def test_start_up(tmp_path: Path) -> None:
    """One turn of each case: the four rows with their targets, each figure a positive time."""
    results = startup.run(tmp_path, runs=1)
    assert [result.case for result in results] == [f"start-up {case.name}" for case in startup.CASES]
    finite(results)
    for result, case in zip(results, startup.CASES, strict=True):
        assert result.unit == "s" and result.emulator[0] > 0 and result.reference[0] > 0
        assert [(check.op, check.bound) for check in result.checks] == [("<=", case.target_s)]
    assert table(results).count("\n") == len(results) + 1
