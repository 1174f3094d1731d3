"""Measuring a running daemon from outside: memory, descriptors, CPU, round-trip latencies."""

from __future__ import annotations

import os
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

import serial

from emulator.control_client import ControlClient

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def rss_mb(pid: int) -> float:
    """Resident set size of `pid` in MB."""
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for pid {pid}")


def fd_count(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def cpu_seconds(pid: int) -> float:
    """User + system CPU time `pid` has used so far."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def cpu_percent(pid: int, seconds: float) -> float:
    """CPU use of `pid` over the next `seconds` of wall time (what an idle daemon must keep at 0)."""
    start_cpu, start = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)  # sampling a rate over an interval: the interval is the measurement
    return 100 * (cpu_seconds(pid) - start_cpu) / (time.monotonic() - start)


def settle(client: ControlClient, device: str) -> None:
    """Until the daemon has noticed every host of `device` left (it handles hang-ups asynchronously)."""
    while any(port["attached"] for d in client.list() if d["device"] == device for port in d["ports"]):
        pass


@dataclass
class Latencies:
    """Round-trip times of one command, in ms."""

    samples: list[float] = field(default_factory=list)

    def p(self, percent: float) -> float:
        if not self.samples:
            return float("nan")
        ordered = sorted(self.samples)
        return ordered[min(len(ordered) - 1, int(len(ordered) * percent / 100))]

    @property
    def p50(self) -> float:
        return statistics.median(self.samples) if self.samples else float("nan")

    @property
    def p99(self) -> float:
        return self.p(99)


def round_trips(
    port: serial.Serial, command: bytes, reply: bytes, count: int, until: float = 0.0
) -> Latencies:
    """`count` round trips (or, with `until`, as many as fit before that monotonic instant), each
    checked against `reply`."""
    result = Latencies()
    while len(result.samples) < count or time.monotonic() < until:
        start = time.perf_counter()
        port.write(command)
        answer = port.read(len(reply))
        result.samples.append((time.perf_counter() - start) * 1000)
        if answer != reply:
            raise AssertionError(f"{command!r} answered {answer!r}, expected {reply!r}")
        if until and time.monotonic() >= until and len(result.samples) >= count:
            break
    return result


def figure(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"
    return str(value)
