"""`--timing realistic`: when bytes and move completions arrive, against the wire and motion models.

The host opens each port with pyserial at the profile's baud (so the daemon paces at it), then reads
the descriptor itself, select + os.read in a tight loop, stamping each byte with time.perf_counter
when the read returns: a stamp includes the host's own read latency, never less. A request's stamp is
taken just before its os.write, when its first character would start on a real wire. The daemon
runs on the least busy CPU and the host on another, as for round trips: left to the scheduler, the
pair migrated between CPUs and the byte error's p99 ranged 0.6-1.4 ms from run to run (0.3-0.9 ms
pinned).

- Byte timing: MS2000 `W X`. Byte k of the reply is due at the end of the request's last character
  + the device's processing time (0: none is documented for it) + k character times (start, data,
  parity and stop bits at the baud). Per request, the worst |arrival − due| of its bytes; reported
  p50 and p99 over the requests. Target: p99 ≤ 1 ms.
- MP-285 `m`: the final CR is due at the end of the request + the move's duration from the profile
  (docs/mp285.md §6: distance / speed, trapezoidal ramps with `accel_um_s2`) + `settle_s` + one
  character. Target: |completion − model| ≤ 1 % of the model's duration + 2 ms.
- MS2000 `M` + `/` polls: the device answers a `/` as its CR ends, so the last `B` and the first `N`
  bracket the completion instant; the error is how far the model's instant (end of the `M` + the
  trapezoid of docs/ms2000.md §5 in encoder counts + `landing_ms` + the axis's `WT`) lies outside the
  bracket (0 inside: the polls cannot resolve finer). Same target as the MP-285's.
"""

from __future__ import annotations

import os
import select
import statistics
import time
from pathlib import Path
from typing import Any

import serial

from protocols.mp285 import Absolute, Move, SetVelocity, axis_factors
from protocols.rounding import round_half_away
from scripts.perf.common import (
    REPLY_TIMEOUT,
    BenchError,
    Check,
    Result,
    ask,
    char_time,
    open_host,
    p50_p99,
    placed,
    profile_values,
    quietest_cpus,
    serve,
    trapezoid_s,
)

BYTE_ERROR_MS = 1.0
#: completion within this share of the model's duration, plus COMPLETION_MS
COMPLETION_SHARE = 0.01
COMPLETION_MS = 2.0
WARMUP = 5

W_X = (b"W X\r", b":A 0\r\n")
#: MP-285 move: 500 µm steps along X at 1000 µm/s (0.5 s + settle)
MP285_SPEED_UM_S = 1000
MP285_STEP_USTEPS = 12_500
#: MS2000 move: 2 mm steps along X (0.1 µm units), forwards only: no anti-backlash leg (MS-57)
MS2000_STEP_UNITS = 20_000


def run(workdir: Path, requests: int, moves: int) -> list[Result]:
    ms2000, mp285 = profile_values("ms2000"), profile_values("mp285")
    daemon = serve(workdir, ["--profile", "ms2000", "--profile", "mp285", "--timing", "realistic"], 2)
    cpus = quietest_cpus()
    try:
        # as for round trips (roundtrip.py): the daemon on the least busy CPU, the host on another
        with placed({daemon.proc.pid: {cpus[0]}, 0: {cpus[1 % len(cpus)]}}):
            return [
                byte_timing(daemon.port("ms2000"), ms2000, requests),
                mp285_moves(daemon.port("mp285"), mp285, moves),
                ms2000_moves(daemon.port("ms2000"), ms2000, moves),
            ]
    finally:
        daemon.stop()


def byte_timing(path: str, values: dict[str, Any], requests: int) -> Result:
    request, expected = W_X
    tick = char_time(values)
    worst: list[float] = []
    errors: list[float] = []
    with open_host(path, values["line.baud"]) as port:
        for index in range(WARMUP + requests):
            sent, stamps = _expect(_fd(port), request, expected)
            ends = [sent + (len(request) + k) * tick for k in range(1, len(expected) + 1)]
            late = [(stamp - end) * 1000 for stamp, end in zip(stamps, ends, strict=True)]
            if index >= WARMUP:
                worst.append(max(abs(e) for e in late))
                errors.extend(late)
    p50, p99 = p50_p99(worst)
    return Result(
        case=f"timing {request.decode().strip()} reply bytes at {values['line.baud']} baud",
        unit="ms",
        emulator=(p50, p99),
        reference=(),
        checks=(Check("p99 error ms", p99, "<=", BYTE_ERROR_MS),),
        details={
            "requests": requests,
            "char_time_ms": tick * 1000,
            "signed_byte_error_ms": {
                "min": min(errors),
                "median": statistics.median(errors),
                "max": max(errors),
            },
        },
    )


def mp285_moves(path: str, values: dict[str, Any], moves: int) -> Result:
    tick = char_time(values)
    usteps_per_um = axis_factors(values["stage.device_type"], values["stage.z_usteps_per_um"])[0]
    accel = values["knobs.accel_um_s2"]
    ramp = MP285_SPEED_UM_S / accel if accel else 0.0
    model = trapezoid_s(MP285_STEP_USTEPS / usteps_per_um, MP285_SPEED_UM_S, ramp) + values["knobs.settle_s"]
    measured = []
    with open_host(path, values["line.baud"]) as port:
        ask(port, Absolute().encode(), b"\r")
        ask(port, SetVelocity.of(MP285_SPEED_UM_S).encode(), b"\r")
        for step in range(1, moves + 1):
            request = Move(step * MP285_STEP_USTEPS, 0, 0).encode()
            sent, (done,) = _expect(_fd(port), request, b"\r", model + REPLY_TIMEOUT)
            measured.append(done - sent - (len(request) + 1) * tick)
    return _completion(
        f"timing mp285 m {MP285_STEP_USTEPS / usteps_per_um:g} µm", [model] * moves, measured, []
    )


def ms2000_moves(path: str, values: dict[str, Any], moves: int) -> Result:
    tick = char_time(values)
    counts_per_mm = values["axes.X.counts_per_mm"]
    units_per_mm = values["axes.X.unit_multiplier"]
    speed = values["axes.X.speed_mm_s"] * counts_per_mm
    ramp = values["axes.X.accel_ms"] / 1000
    pause = (values["knobs.landing_ms"] + values["axes.X.wait_ms"]) / 1000
    position = 0
    models, measured, brackets = [], [], []
    with open_host(path, values["line.baud"]) as port:
        for step in range(1, moves + 1):
            target = round_half_away(step * MS2000_STEP_UNITS / units_per_mm * counts_per_mm)
            models.append(trapezoid_s(target - position, speed, ramp) + pause)
            position = target
            request = f"M X={step * MS2000_STEP_UNITS}\r".encode()
            sent, _ = _expect(_fd(port), request, b":A\r\n")
            start = sent + len(request) * tick  # the move starts as the request's CR ends
            busy_until, idle_from = _poll(_fd(port), start, tick, models[-1] + REPLY_TIMEOUT)
            brackets.append((busy_until - start, idle_from - start))
            # the figure: the bracket's point nearest the model (the polls cannot tell them apart)
            measured.append(min(max(models[-1], brackets[-1][0]), brackets[-1][1]))
    return _completion(
        f"timing ms2000 M X {MS2000_STEP_UNITS / units_per_mm:g} mm, bracketed by / polls",
        models,
        measured,
        [(low * 1000, high * 1000) for low, high in brackets],
    )


def _completion(
    case: str, models: list[float], measured: list[float], brackets: list[tuple[float, float]]
) -> Result:
    """Moves against their models; the bound is the strictest (shortest) move's."""
    worst = max(abs(m - model) for m, model in zip(measured, models, strict=True)) * 1000
    details: dict[str, Any] = {"moves": len(measured), "measured_ms": [m * 1000 for m in measured]}
    if brackets:
        details["poll_brackets_ms"] = brackets
    return Result(
        case=case,
        unit="ms",
        emulator=(statistics.median(measured) * 1000,),
        reference=(statistics.median(models) * 1000,),
        checks=(Check("worst error ms", worst, "<=", COMPLETION_SHARE * min(models) * 1000 + COMPLETION_MS),),
        details=details,
    )


def _fd(port: serial.Serial) -> int:
    """The open port's descriptor, read and written directly from here on."""
    if port.fd is None:
        raise BenchError(f"{port.port} is not open")
    return port.fd


def _poll(fd: int, start: float, tick: float, timeout: float) -> tuple[float, float]:
    """`/` until `N`: the instants the last `B` and the first `N` were decided (each `/`'s CR end)."""
    busy_until = start
    while True:
        sent, reply, _ = _exchange(fd, b"/\r", 3)
        decided = sent + 2 * tick
        if reply == b"N\r\n":
            return busy_until, decided
        if reply != b"B\r\n":
            raise BenchError(f"/ answered {reply!r} during a move")
        if decided - start > timeout:
            raise BenchError(f"MS2000 move still busy {timeout:.1f} s after it started")
        busy_until = decided


def _expect(
    fd: int, request: bytes, expected: bytes, timeout: float = REPLY_TIMEOUT
) -> tuple[float, list[float]]:
    """`_exchange` whose reply must be exactly `expected`: (write instant, byte stamps)."""
    sent, reply, stamps = _exchange(fd, request, len(expected), timeout)
    if reply != expected:
        raise BenchError(f"{request!r} answered {reply!r}, expected {expected!r}")
    return sent, stamps


def _exchange(
    fd: int, request: bytes, length: int, timeout: float = REPLY_TIMEOUT
) -> tuple[float, bytes, list[float]]:
    """Write `request`, read `length` reply bytes as they arrive: (write instant, reply, byte stamps)."""
    sent = time.perf_counter()
    os.write(fd, request)
    reply = bytearray()
    stamps: list[float] = []
    deadline = sent + timeout
    while len(reply) < length:
        left = deadline - time.perf_counter()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            raise BenchError(
                f"{request!r}: {len(reply)} of {length} reply bytes in {timeout:.1f} s: {bytes(reply)!r}"
            )
        chunk = os.read(fd, length - len(reply))
        stamps += [time.perf_counter()] * len(chunk)
        reply += chunk
    return sent, bytes(reply), stamps
