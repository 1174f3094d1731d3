"""`--time-scale`: a long MS2000 move runs in its duration / scale of wall time and lands where it
would at scale 1.

The target is chosen so that the move lasts `seconds` of device time by the model of docs/ms2000.md §5
(factory S and AC from the profile, whole encoder counts). The host times `M X=…` to the first `/`
answering `N`, then reads `W X`. The scale-1 position is computed, not run: the axis lands exactly on
its target count (MS-53), which `W X` prints in the axis's units.
Targets (issue "Speed"): wall time ≤ 1.1 × duration / scale (110 ms for 10 s at 100), and the same
`W X` as at scale 1.
"""

from __future__ import annotations

import time
from pathlib import Path

from protocols.ms2000 import where
from protocols.rounding import round_half_away
from scripts.perf.common import (
    BenchError,
    Check,
    Result,
    ask,
    open_host,
    profile_values,
    read_reply,
    serve,
    trapezoid_s,
)

WALL_SHARE = 1.10
#: polls after which the move counts as hung (10^5 polls of 50 µs of wire time each at scale 100)
MAX_POLLS = 100_000


def run(workdir: Path, scale: float, seconds: float) -> Result:
    values = profile_values("ms2000")
    counts_per_mm = values["axes.X.counts_per_mm"]
    units_per_mm = values["axes.X.unit_multiplier"]
    speed_mm_s = values["axes.X.speed_mm_s"]
    ramp = values["axes.X.accel_ms"] / 1000
    pause = (values["knobs.landing_ms"] + values["axes.X.wait_ms"]) / 1000
    units = round_half_away(_distance_mm(seconds - pause, speed_mm_s, ramp) * units_per_mm)
    counts = round_half_away(units / units_per_mm * counts_per_mm)
    model = trapezoid_s(counts, speed_mm_s * counts_per_mm, ramp) + pause
    expected = f":A {where(counts / counts_per_mm * units_per_mm)}\r\n".encode()

    args = ["--profile", "ms2000", "--timing", "realistic", "--time-scale", f"{scale:g}"]
    daemon = serve(workdir, args, 1)
    try:
        with open_host(daemon.port("ms2000")) as port:
            start = time.perf_counter()
            ask(port, f"M X={units}\r".encode(), b":A\r\n")
            for _ in range(MAX_POLLS):
                port.write(b"/\r")
                reply = read_reply(port, 3, "/")
                if reply == b"N\r\n":
                    break
                if reply != b"B\r\n":
                    raise BenchError(f"/ answered {reply!r} during a move")
            else:
                raise BenchError(
                    f"move of {model:.1f} s at scale {scale:g} still busy after {MAX_POLLS} polls"
                )
            wall = time.perf_counter() - start
            port.write(b"W X\r")
            position = port.read_until(b"\r\n")
    finally:
        daemon.stop()
    if not position.startswith(b":A ") or not position.endswith(b"\r\n"):
        raise BenchError(f"W X answered {position!r}")
    return Result(
        case=f"time scale {scale:g}: {model:.3g} s ms2000 move, then W X",
        unit="ms",
        emulator=(wall * 1000,),
        reference=(model / scale * 1000,),
        checks=(
            Check("wall ms", wall * 1000, "<=", WALL_SHARE * model / scale * 1000),
            Check("W X − scale 1", abs(float(position[3:-2]) - float(expected[3:-2])), "<=", 0.0),
        ),
        details={
            "target_units": units,
            "model_s": model,
            "w_x": position.decode(),
            "w_x_at_scale_1": expected.decode(),
        },
    )


def _distance_mm(duration: float, speed: float, ramp: float) -> float:
    """The distance a move from rest to rest covers in `duration` (the inverse of `trapezoid_s`)."""
    if duration >= 2 * ramp:  # always with no ramp
        return (duration - ramp) * speed
    return speed / ramp * (duration / 2) ** 2
