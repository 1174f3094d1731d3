"""Torture suite: attack daemons the way hostile or broken hosts do, print a table of figures, exit 1
when a bound is exceeded (`make soak`; short forms of each attack run in `make test`).

    python scripts/torture.py [--quick] [--only ATTACK ...] [--examples N] [--json FILE]

Attacks: flood (random bytes at full speed into every port), netflood (the same from a TCP and an
RFC 2217 client that never reads), cycles (open/close every port),
kill (kill -9 during `SS Z`, restart), subscriber (control client that never reads), starvation
(devices with more work than the CPU can do at time scale 10 000, a neighbour polled), urlwrites
(writes of up to 64 KiB on `stageemu://` ports), signals,
profiles (the hostile-profile corpus through `stage-emu validate`), readers (hostile and huge
inputs for `trace`, `plot`, `replay` and `gcode --dry-run`), fuzz (hypothesis examples per
protocol model), modules (hypothesis examples per MS2000 module-command property and build).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scripts.soak import attacks  # noqa: E402
from scripts.soak.attacks import Outcome  # noqa: E402
from scripts.soak.hostile_profiles import write_cases  # noqa: E402
from scripts.soak.hostile_readers import hostile_readers, run_command  # noqa: E402
from scripts.soak.kill_save import kill_during_save  # noqa: E402
from scripts.soak.probes import figure  # noqa: E402
from scripts.soak.starvation import time_scale_starvation  # noqa: E402
from scripts.soak.url_writes import url_writes  # noqa: E402

FUZZ_FILES = ("tests/unit/mp285/test_mp285_fuzz.py", "tests/unit/ms2000/test_fuzz.py")
#: the firmware modules' commands with hostile items, on every build that carries them
MODULE_FUZZ_FILES = ("tests/unit/ms2000/test_fuzz_modules.py",)
#: a hostile profile must be refused within this much wall time and memory
PROFILE_SECONDS = 1.0
PROFILE_RSS_MB = 100.0


def hostile_profiles(workdir: Path) -> Outcome:
    """Each case of the corpus through `stage-emu validate`: a one-line error, fast, small."""
    out = Outcome("hostile profiles through `stage-emu validate`")
    workdir.mkdir(parents=True, exist_ok=True)
    slowest, largest = 0.0, 0.0
    cases = write_cases(workdir)
    for name, path, expected in cases:
        run = run_command(["validate", str(path)])
        slowest, largest = max(slowest, run.seconds), max(largest, run.rss_mb)
        lines = run.stderr.strip().splitlines()
        out.bound(run.code == 1, f"{name}: exit {run.code}")
        out.bound(len(lines) == 1 and expected in run.stderr, f"{name}: not one line with {expected!r}")
        out.bound(run.seconds < PROFILE_SECONDS, f"{name}: took {run.seconds:.2f} s")
        out.bound(run.rss_mb < PROFILE_RSS_MB, f"{name}: {run.rss_mb:.0f} MB")
    out.figures.update(cases=len(cases), slowest_s=slowest, max_rss_mb=largest)
    return out


def fuzz(examples: int, files: tuple[str, ...], what: str) -> Outcome:
    """The hypothesis properties of `files`, randomized, `examples` each (what `make test` runs as a
    short derandomized set)."""
    out = Outcome(f"hypothesis examples per {what} ({examples})")
    start = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *files],
        cwd=ROOT,
        env={**os.environ, "STAGE_EMU_SOAK_EXAMPLES": str(examples)},
        capture_output=True,
        text=True,
    )
    summary = (result.stdout.strip().splitlines() or ["no output"])[-1]
    out.figures.update(examples=examples, minutes=(time.monotonic() - start) / 60, pytest=summary)
    out.bound(result.returncode == 0, f"fuzz failed: {summary}")
    return out


def kill(workdir: Path, cycles: int) -> Outcome:
    out = Outcome("kill -9 during `SS Z`, then restart")
    try:
        figures = kill_during_save(cycles, workdir / "state", workdir=workdir / "runs")
    except AssertionError as exc:
        out.exceeded.append(str(exc))
        return out
    out.figures.update(figures)
    return out


def plan(args: argparse.Namespace, work: Path) -> dict[str, Callable[[], Outcome]]:
    quick = args.quick
    return {
        "flood": lambda: attacks.flood(work / "flood", seconds=5 if quick else 60),
        "netflood": lambda: attacks.network_flood(work / "netflood", seconds=5 if quick else 60),
        "cycles": lambda: attacks.open_close(work / "cycles", cycles=300 if quick else 10_000),
        "kill": lambda: kill(work / "kill", cycles=10 if quick else 1000),
        "subscriber": lambda: attacks.slow_subscriber(work / "subscriber", seconds=5 if quick else 60),
        "starvation": lambda: time_scale_starvation(work / "starvation", seconds=5 if quick else 30),
        "urlwrites": lambda: url_writes(work / "urlwrites", writes=30 if quick else 200),
        "signals": lambda: attacks.stop_signals(work / "signals"),
        "profiles": lambda: hostile_profiles(work / "profiles"),
        "readers": lambda: hostile_readers(
            work / "readers", log_mb=5 if quick else 40, gcode_moves=100_000 if quick else 2_000_000
        ),
        "fuzz": lambda: fuzz(200 if quick else args.examples, FUZZ_FILES, "protocol model"),
        "modules": lambda: fuzz(
            100 if quick else args.examples, MODULE_FUZZ_FILES, "module-command property and build"
        ),
    }


def table(outcomes: list[Outcome]) -> str:
    rows = [("attack", "figures", "outcome")]
    for out in outcomes:
        figures = ", ".join(f"{k} {figure(v)}" for k, v in out.figures.items())
        rows.append((out.attack, figures, "pass" if out.passed else "FAIL: " + "; ".join(out.exceeded)))
    return "\n".join(f"| {' | '.join(row)} |" for row in [rows[0], ("---",) * 3, *rows[1:]])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="seconds, not minutes: a smoke run")
    parser.add_argument("--only", nargs="+", metavar="ATTACK", help="run only these attacks")
    parser.add_argument("--examples", type=int, default=10_000, help="hypothesis examples per model")
    parser.add_argument("--json", type=Path, help="also write the outcomes here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="stage-emu-torture-") as tmp:
        steps = plan(args, Path(tmp))
        unknown = set(args.only or ()) - set(steps)
        if unknown:
            parser.error(f"unknown attack(s) {', '.join(sorted(unknown))}; known: {', '.join(steps)}")
        outcomes = []
        for name, run in steps.items():
            if args.only and name not in args.only:
                continue
            print(f"torture: {name}...", file=sys.stderr, flush=True)
            try:
                outcomes.append(run())
            except Exception as exc:  # an attack that breaks is a failed row, not a lost table
                outcomes.append(Outcome(name, exceeded=[f"the attack failed: {type(exc).__name__}: {exc}"]))
    print(table(outcomes))
    if args.json:
        args.json.write_text(json.dumps([o.__dict__ for o in outcomes], indent=1, default=str) + "\n")
    return 0 if all(o.passed for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
