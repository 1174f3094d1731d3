"""Time-scale starvation: devices with more model work per wall second than the CPU can do.

Three devices run work that scales with device time (a SEQUENCER stepping every millisecond, an
ARRAY of a million tiny cells, an engaged CRISP lock updating every 10 ms) and the clock is set to
10 000 device seconds per wall second. Each falls behind the clock (emulator/hosting/lag.py) instead of
holding the loop: a neighbour device and the control channel keep answering, memory stays flat, and
SIGTERM ends the daemon at once. Figures: the neighbour's `W X` and a control `list` round trip
(p99, ms) while starved, the daemon's RSS before and after, how far behind each device got, how
long SIGTERM took.
"""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass
from pathlib import Path

import serial

from emulator.control_client import ControlClient
from emulator.hosting.launcher import RunningDaemon, start_daemon, write_rig
from scripts.soak.attacks import Outcome
from scripts.soak.probes import Latencies, round_trips, rss_mb

NEIGHBOUR = "measured"
SCALE = 10_000.0
#: loop latency allowed while starved: what a neighbour, a signal or a control request may wait
LATENCY_MS = 50.0
RSS_GROWTH_MB = 10.0
SIGTERM_S = 1.0
#: the loads: device name, profile, control-channel setup, host commands (each answered `:A`)
LOADS: tuple[tuple[str, str, dict[str, object] | None, tuple[bytes, ...]], ...] = (
    (
        "seq",
        "ms2000-seq",
        {"in": "sequencer", "blocks": [{"start": [12], "repeat": [12], "delay_ms": 1, "repetitions": 65535}]},
        (b"ARM X\r",),
    ),
    (
        "array",
        "ms2000-all-modules",
        None,
        (b"AR X=1000 Y=1000 Z=0.000001 F=0.000001\r", b"RT Z=0\r", b"AH\r", b"AR\r"),
    ),
    ("crisp", "ms2000-crisp", None, (b"LK\r", b"LK\r")),
)


@dataclass
class Starved:
    """What the starvation run measured."""

    neighbour: Latencies
    control: Latencies
    rss_before_mb: float
    rss_after_mb: float
    behind_s: dict[str, float]
    lag_warnings: int
    sigterm_s: float
    exit_code: int | None


def starve(workdir: Path, seconds: float) -> Starved:
    """Run the loads at `SCALE` for `seconds` while polling the neighbour and the control channel."""
    devices = [(name, profile) for name, profile, _, _ in LOADS] + [(NEIGHBOUR, "ms2000")]
    rig = write_rig(workdir, devices, "realistic")
    daemon = start_daemon(
        workdir, [str(rig), "--state-dir", str(workdir / "state")], expect_ports=len(devices)
    )
    try:
        control = daemon.control()
        _start_loads(daemon, control)
        pid = daemon.proc.pid
        with serial.Serial(daemon.port(NEIGHBOUR), 9600, timeout=5) as port:
            round_trips(port, b"W X\r", b":A 0\r\n", count=20)  # warm: the first trips build caches
            before = rss_mb(pid)
            control.clock(scale=SCALE)
            neighbour, requests = Latencies(), Latencies()
            until = time.monotonic() + seconds
            while time.monotonic() < until:
                neighbour.samples += round_trips(port, b"W X\r", b":A 0\r\n", count=1).samples
                start = time.perf_counter()
                listing = control.list()
                requests.samples.append((time.perf_counter() - start) * 1000)
            after = rss_mb(pid)
        behind = {d["device"]: d["behind_s"] for d in listing if d["device"] != NEIGHBOUR}
        start = time.monotonic()
        code = daemon.stop(signal.SIGTERM, timeout=30)
        took = time.monotonic() - start
    finally:
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    warnings = sum("cannot keep up with the clock" in line for line in daemon.log.lines)
    return Starved(neighbour, requests, before, after, behind, warnings, took, code)


def _start_loads(daemon: RunningDaemon, control: ControlClient) -> None:
    for name, _, setup, commands in LOADS:
        if setup is not None:
            control.request({"device": name, **setup})
        with serial.Serial(daemon.port(name), 9600, timeout=5) as port:
            for command in commands:
                port.write(command)
                answer = port.read_until(b"\n")
                if not answer.startswith(b":A"):
                    raise AssertionError(f"{name}: {command!r} answered {answer!r}")


def time_scale_starvation(workdir: Path, seconds: float = 30.0) -> Outcome:
    """The torture suite's attack: bounds on the starved daemon (issue "Hardening, round two")."""
    out = Outcome(f"time-scale starvation: {len(LOADS)} devices at scale {SCALE:g}, a neighbour polled")
    run = starve(workdir, seconds)
    out.figures.update(
        seconds=seconds,
        neighbour_p99_ms=run.neighbour.p99,
        control_p99_ms=run.control.p99,
        neighbour_trips=len(run.neighbour.samples),
        rss_before_mb=run.rss_before_mb,
        rss_after_mb=run.rss_after_mb,
        behind_s=min(run.behind_s.values(), default=0.0),
        lag_warnings=run.lag_warnings,
        sigterm_s=run.sigterm_s,
    )
    out.bound(run.neighbour.p99 <= LATENCY_MS, f"neighbour p99 > {LATENCY_MS} ms")
    out.bound(run.control.p99 <= LATENCY_MS, f"control p99 > {LATENCY_MS} ms")
    out.bound(run.rss_after_mb - run.rss_before_mb < RSS_GROWTH_MB, f"RSS grew by >= {RSS_GROWTH_MB} MB")
    out.bound(all(behind > 0 for behind in run.behind_s.values()), "a loaded device kept up (no starvation)")
    out.bound(run.lag_warnings == len(LOADS), "not one 'cannot keep up' line per loaded device")
    out.bound(run.exit_code == 0 and run.sigterm_s <= SIGTERM_S, f"SIGTERM not obeyed within {SIGTERM_S} s")
    return out
