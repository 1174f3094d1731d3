"""Hostile and huge inputs for the offline readers: `stage-emu trace`, `plot`, `replay` and
`gcode --dry-run` (issue "Hardening, round two", item 5). Big files are generated, never committed.

`hostile_readers(workdir)` builds each case and runs each command it applies to as a child process,
measuring wall time and the child's own peak memory (scripts/soak/peak_rss.py says why not only
os.wait4's). A hostile input (an endless device, a FIFO with no
writer, a huge single line, deep JSON nesting, binary garbage, an empty file) must give one line on
stderr and the command's bad-input exit status within `HOSTILE_SECONDS` and `RSS_MB`; a big valid
input (a traffic log of tens of MB, a G-code program of 2 M moves) must complete within `RSS_MB`
(its time is a figure, bounded only generously).
"""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scripts.soak.attacks import Outcome
from scripts.soak.peak_rss import ENV as PEAK_ENV

ROOT = Path(__file__).resolve().parents[2]
HOSTILE_SECONDS = 1.0
RSS_MB = 100.0
#: a big valid input may take this long (a figure of the soak, not a tight bound)
BIG_SECONDS = 300.0
#: how long a child may run before it is killed as hung
WATCHDOG_S = 600.0
#: each command and the exit status it documents for bad input
COMMANDS: dict[str, tuple[Callable[[Path, Path], list[str]], int]] = {
    "trace": (lambda path, _out: ["trace", str(path)], 1),
    "plot": (lambda path, out: ["plot", str(path), "-o", str(out / "plot.png")], 1),
    "replay": (lambda path, _out: ["replay", str(path), "--timing", "fast"], 2),
    "gcode": (lambda path, _out: ["gcode", str(path), "--dry-run"], 1),
}


@dataclass(frozen=True)
class Run:
    code: int
    stderr: str
    seconds: float
    rss_mb: float


def run_command(args: list[str]) -> Run:
    """`stage-emu ARGS` as a child: exit status, stderr, wall seconds and peak RSS (MB): its own
    (scripts/soak/peak_rss.py), else, if it died before saying, what os.wait4 says of it."""
    with tempfile.TemporaryFile("w+") as err, tempfile.TemporaryDirectory() as scratch:
        peak = Path(scratch) / "peak_kb"
        start = time.monotonic()
        proc = subprocess.Popen(
            [sys.executable, "-m", "scripts.soak.peak_rss", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=err,
            cwd=ROOT,
            env={**os.environ, PEAK_ENV: str(peak)},
        )
        watchdog = threading.Timer(WATCHDOG_S, proc.kill)  # a hang is a failure, not a stuck soak
        watchdog.start()
        _, status, usage = os.wait4(proc.pid, 0)
        watchdog.cancel()
        took = time.monotonic() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        said = peak.read_text().strip() if peak.exists() else ""
        rss_kb = int(said) if said.isdigit() else usage.ru_maxrss
        return Run(proc.returncode, err.read(), took, rss_kb / 1024)


# ---- the inputs ---------------------------------------------------------------------------------


def write_big_log(path: Path, megabytes: float) -> int:
    """A valid traffic log of about `megabytes` MB: a serpentine raster of moves (a host's `M`, the
    reply, the move's knots, its completion) with OUT0 on along each line; returns the moves."""
    moves = 0
    with path.open("w") as out:
        size, t, x, y = 0, 2.0, 0.0, 0.0
        while size < megabytes * 1e6:
            line, step = divmod(moves, 200)
            target_x = (step if line % 2 == 0 else 199 - step) * 50.0
            target_y = line * 20.0
            records = [
                {
                    "t": t,
                    "wall": 1e9 + t,
                    "device": "stage",
                    "port": "main",
                    "dir": "rx",
                    "hex": "4d 20 58 0d",
                }
                | {"kind": "frame", "summary": f"M X={target_x * 10:g} Y={target_y * 10:g} [MOVE]"},
                {"t": t + 0.004, "wall": 1e9 + t, "device": "stage", "port": "main", "dir": "tx"}
                | {"hex": "3a 41 0d 0a", "kind": "reply", "summary": "reply to M: :A"},
                {"t": t, "wall": 1e9 + t, "device": "stage", "dir": "ev", "ev": "move"}
                | {"path": {"X": [[t, x], [t + 0.05, target_x]], "Y": [[t, y], [t + 0.05, target_y]]}},
                {"t": t + 0.05, "wall": 1e9 + t, "device": "stage", "dir": "ev", "ev": "move_complete"},
            ]
            if step == 0:
                records.append({"t": t, "wall": 1e9 + t, "device": "stage", "dir": "ev", "ev": "ttl_out0"})
                records[-1]["level"] = line % 2
            text = "".join(json.dumps(record) + "\n" for record in records)
            out.write(text)
            size += len(text)
            x, y, t, moves = target_x, target_y, t + 0.1, moves + 1
    return moves


def write_big_gcode(path: Path, moves: int) -> None:
    """A G-code program of `moves` G01 moves (a zigzag; about 13 bytes a line)."""
    with path.open("w") as out:
        out.write("G21 G90 G01 F600\n")
        batch = 10_000
        for first in range(0, moves, batch):
            out.write("".join(f"X{i % 97} Y{i % 89}\n" for i in range(first, min(first + batch, moves))))


def hostile_inputs(workdir: Path) -> dict[str, Path]:
    """Each hostile case: name -> path (`/dev/zero` itself for an endless file)."""
    cases = {"dev_zero": Path("/dev/zero")}
    fifo = workdir / "fifo.jsonl"
    if not fifo.exists():
        os.mkfifo(fifo)  # no writer ever opens it
    cases["fifo"] = fifo
    huge = workdir / "huge_line.jsonl"
    with huge.open("wb") as out:  # 64 MB without a newline
        out.write(b'{"t": 1, "hex": "')
        chunk = b"41 " * (1 << 20)
        for _ in range(21):
            out.write(chunk)
    cases["huge_line"] = huge
    deep = workdir / "deep.jsonl"
    deep.write_text("[" * 100_000 + "\n")
    cases["deep_nesting"] = deep
    garbage = workdir / "garbage.bin"
    garbage.write_bytes(random.Random(7).randbytes(4 << 20))
    cases["binary_garbage"] = garbage
    empty = workdir / "empty.jsonl"
    empty.write_bytes(b"")
    cases["empty"] = empty
    return cases


# ---- the attack ---------------------------------------------------------------------------------


def hostile_readers(workdir: Path, *, log_mb: float = 40.0, gcode_moves: int = 2_000_000) -> Outcome:
    """Every hostile case through every command, then the big valid inputs (see the docstring)."""
    out = Outcome("hostile and huge files through trace, plot, replay, gcode --dry-run")
    workdir.mkdir(parents=True, exist_ok=True)
    slowest = largest = 0.0
    cases = 0
    for name, path in hostile_inputs(workdir).items():
        for command, (arguments, bad_input) in COMMANDS.items():
            result = run_command(arguments(path, workdir))
            cases += 1
            slowest, largest = max(slowest, result.seconds), max(largest, result.rss_mb)
            lines = result.stderr.strip().splitlines()
            what = f"{command} {name}"
            out.bound(result.code == bad_input, f"{what}: exit {result.code}, not {bad_input}")
            out.bound(
                len(lines) == 1 and lines[0].startswith(f"stage-emu: {path}"),
                f"{what}: not one line naming the file: {result.stderr[:200]!r}",
            )
            out.bound(result.seconds < HOSTILE_SECONDS, f"{what}: took {result.seconds:.2f} s")
            out.bound(result.rss_mb < RSS_MB, f"{what}: {result.rss_mb:.0f} MB")
    log = workdir / "big.jsonl"
    write_big_log(log, log_mb)
    program = workdir / "big.nc"
    write_big_gcode(program, gcode_moves)
    big = {
        "trace_big_log": ["trace", str(log)],
        "plot_big_log": ["plot", str(log), "-o", str(workdir / "big.png")],
        "gcode_big_program": ["gcode", str(program), "--dry-run"],
    }
    for name, args in big.items():
        result = run_command(args)
        cases += 1
        largest = max(largest, result.rss_mb)
        out.figures[f"{name}_s"] = result.seconds
        out.figures[f"{name}_mb"] = result.rss_mb
        out.bound(result.code == 0, f"{name}: exit {result.code}: {result.stderr[:200]!r}")
        out.bound(result.seconds < BIG_SECONDS, f"{name}: took {result.seconds:.0f} s")
        out.bound(result.rss_mb < RSS_MB, f"{name}: {result.rss_mb:.0f} MB")
    out.figures.update(cases=cases, slowest_s=slowest, max_rss_mb=largest)
    return out
