"""What every measurement shares: the `Result` shape, statistics, daemons, profile values, the host's
port and the wire and motion models the targets are stated in."""

from __future__ import annotations

import contextlib
import json
import math
import operator
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import serial

from emulator.hosting.launcher import RunningDaemon, start_daemon

ROOT = Path(__file__).resolve().parents[2]
#: a reply later than this is a hung daemon or floor, not a slow one: the bench stops, loudly
REPLY_TIMEOUT = 5.0

_OPS = {"<=": operator.le, ">=": operator.ge, "<": operator.lt}


class BenchError(RuntimeError):
    """A measurement that could not be made: a wrong reply, a timeout. Never a missed target."""


@dataclass(frozen=True)
class Check:
    """One target: `value` compared with `bound` (`op`), both in the unit the name implies."""

    name: str
    value: float
    op: Literal["<=", ">=", "<"]
    bound: float

    @property
    def passed(self) -> bool:
        return bool(_OPS[self.op](self.value, self.bound))  # NaN fails every comparison

    def describe(self) -> str:
        return f"{self.name} {figure(self.value)} (target {self.op} {figure(self.bound)})"


@dataclass(frozen=True)
class Result:
    """One row of the table. `emulator` and `reference` are the compared figures in `unit`: p50 and p99
    for latencies, one figure otherwise. The reference is what a relative target is relative to (the
    no-parsing floor, one busy port, the motion model); empty for absolute targets."""

    case: str
    unit: str
    emulator: tuple[float, ...]
    reference: tuple[float, ...]
    checks: tuple[Check, ...]
    details: dict[str, Any] = field(default_factory=dict)
    #: figures shown for reference, with no target: (name, value)
    info: tuple[tuple[str, float], ...] = ()

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    def failures(self) -> list[str]:
        return [f"{self.case}: {check.describe()}" for check in self.checks if not check.passed]

    def as_json(self) -> dict[str, Any]:
        return {**asdict(self), "passed": self.passed}


def figure(value: float) -> str:
    """A figure for the table: three significant digits, whole numbers from 1000 up."""
    if math.isnan(value):
        return "nan"
    return f"{value:.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def percentile(samples: Sequence[float], percent: float) -> float:
    """Nearest-rank percentile (p99 of 200 samples is the second largest)."""
    ordered = sorted(samples)
    return ordered[max(1, math.ceil(len(ordered) * percent / 100)) - 1]


def p50_p99(samples: Sequence[float]) -> tuple[float, float]:
    return statistics.median(samples), percentile(samples, 99)


# ---- daemons, profiles, host ports ----------------------------------------------------------------


def serve(workdir: Path, args: list[str], ports: int) -> RunningDaemon:
    """`stage-emu serve ARGS` from this checkout, ready with `ports` ports."""
    return start_daemon(workdir, args, ports, cwd=ROOT)


def profile_values(profile: str) -> dict[str, Any]:
    """A bundled profile's settings by dotted path, as `stage-emu describe --json` prints them: the
    expected timings come from the documented inputs, not from the emulator's internals."""
    out = subprocess.run(
        [sys.executable, "-m", "emulator.cli", "describe", profile, "--json"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if out.returncode:
        said = (out.stderr.strip().splitlines() or ["nothing"])[-1]
        raise BenchError(f"`stage-emu describe {profile} --json` exited {out.returncode}: {said}")
    return {entry["path"]: entry["value"] for entry in json.loads(out.stdout)}


def open_host(path: str, baud: int = 9600) -> serial.Serial:
    return serial.Serial(path, baud, timeout=REPLY_TIMEOUT)


def read_reply(port: serial.Serial, length: int, what: str) -> bytes:
    reply = port.read(length)
    if len(reply) != length:
        raise BenchError(f"{what}: {len(reply)} of {length} reply bytes in {REPLY_TIMEOUT} s: {reply!r}")
    return reply


def ask(port: serial.Serial, request: bytes, expected: bytes) -> None:
    """One exchange whose reply must be exactly `expected` (set-up steps, checks)."""
    port.write(request)
    reply = read_reply(port, len(expected), repr(request))
    if reply != expected:
        raise BenchError(f"{request!r} answered {reply!r}, expected {expected!r}")


# ---- where a round trip runs -----------------------------------------------------------------------


def quietest_cpus(window_s: float = 0.03) -> list[int]:
    """The CPUs this process may use, least busy over the next `window_s` first."""
    before = _busy_ticks()
    time.sleep(window_s)  # sampling a rate over an interval: the interval is the measurement
    after = _busy_ticks()
    return sorted(os.sched_getaffinity(0), key=lambda cpu: after[cpu] - before[cpu])


def _busy_ticks() -> dict[int, int]:
    """Per CPU, clock ticks spent on anything but idle and I/O wait (/proc/stat)."""
    busy = {}
    with open("/proc/stat") as stat:
        for line in stat:
            name, *fields = line.split()
            if name.startswith("cpu") and name != "cpu":
                user, nice, system, _idle, _iowait, irq, softirq, steal = map(int, fields[:8])
                busy[int(name[3:])] = user + nice + system + irq + softirq + steal
    return busy


@contextlib.contextmanager
def placed(cpus: Mapping[int, set[int]]) -> Iterator[None]:
    """Every thread of each pid on the CPUs given for it (pid 0: only the calling thread, as for
    sched_setaffinity); the previous affinities are put back afterwards."""
    saved: dict[int, set[int]] = {}
    try:
        for pid, allowed in cpus.items():
            tasks = [0] if pid == 0 else [int(task) for task in os.listdir(f"/proc/{pid}/task")]
            for task in tasks:
                saved[task] = os.sched_getaffinity(task)
                os.sched_setaffinity(task, allowed)
        yield
    finally:
        for task, allowed in saved.items():
            with contextlib.suppress(ProcessLookupError):  # a floor responder already stopped
                os.sched_setaffinity(task, allowed)


# ---- the models the targets are stated in ---------------------------------------------------------


def char_time(values: dict[str, Any]) -> float:
    """Seconds one character takes on the profile's line: start, data, parity and stop bits."""
    parity = 0 if values["line.parity"] == "none" else 1
    bits = 1 + values["line.data_bits"] + parity + values["line.stop_bits"]
    return float(bits / values["line.baud"])


def trapezoid_s(distance: float, speed: float, ramp: float) -> float:
    """Duration of a move from rest to rest that accelerates for `ramp` s up to `speed` and brakes
    alike, or a triangle when too short to reach `speed` (docs/mp285.md §6, docs/ms2000.md §5)."""
    if distance == 0:
        return 0.0
    if ramp == 0 or distance >= speed * ramp:
        return distance / speed + ramp
    return 2 * math.sqrt(distance * ramp / speed)
