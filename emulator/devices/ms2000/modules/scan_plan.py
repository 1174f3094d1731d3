"""The legs of a SCAN run (MS-SCAN-3, MS-SCAN-4, MS-SCAN-7): which axis moves where, in which state.

Raster, per line: the slow axis to the line (`a`), on the first line the fast axis to the start less
the overshoot (`b`), the active sweep at `S` to the stop plus the overshoot (`c`), the retrace at
67 % of the maximum speed back to the start less the overshoot (`g`; after the last line to the start
itself). Serpentine sweeps alternate direction, the backward ones in state `e`, and one final move
takes the fast axis back to its start (`g`). The overshoot distance is `NV F × S × AC / 2000` mm, the
distance the fast axis needs to reach `S`, so the active region is crossed at constant speed.
Positions are user millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis

#: MS-SCAN-4: retrace (and the fast axis's other positioning moves [choice]) at 67 % of max speed
RETRACE_SHARE = 0.67
# MS-SCAN-7 states of the moves
SLOW_MOVE, FAST_START, SWEEP, SERPENTINE_SWEEP, RETRACE = "a", "b", "c", "e", "g"


@dataclass(frozen=True)
class Sweep:
    """The active part of a line: SYNC where it begins, the last pixel where it ends."""

    line: int  # 1-based [choice]
    begin_mm: float
    end_mm: float


@dataclass(frozen=True)
class Leg:
    state: str
    axis: Axis
    goal_mm: float
    speed_mm_s: float | None = None  # None: the axis's own S
    sweep: Sweep | None = None


@dataclass(frozen=True)
class ScanArea:
    fast_start: float
    fast_stop: float
    slow_start: float
    slow_stop: float
    lines: int
    overshoot: float  # factor of the ramp distance (NV F)
    serpentine: bool


def overshoot_mm(axis: Axis, factor: float) -> float:
    """NV F × S × AC / 2000: the distance covered while ramping to S (MS-SCAN-4)."""
    speed = min(axis.s.speed, axis.max_speed)
    return factor * speed * axis.s.accel_ms / 2000


def line_position(area: ScanArea, k: int) -> float:
    """Slow-axis position of line k (0-based): evenly from start to stop (MS-SCAN-3)."""
    if area.lines <= 1:
        return area.slow_start
    return area.slow_start + k * (area.slow_stop - area.slow_start) / (area.lines - 1)


def plan(area: ScanArea, fast: Axis, slow: Axis | None) -> list[Leg]:
    direction = 1.0 if area.fast_stop >= area.fast_start else -1.0
    margin = direction * overshoot_mm(fast, area.overshoot)
    before, after = area.fast_start - margin, area.fast_stop + margin
    retrace = RETRACE_SHARE * fast.max_speed
    legs: list[Leg] = []
    for k in range(area.lines):
        line = k + 1
        if slow is not None:
            legs.append(Leg(SLOW_MOVE, slow, line_position(area, k)))
        if k == 0:
            legs.append(Leg(FAST_START, fast, before, retrace))
        if not area.serpentine:
            legs.append(Leg(SWEEP, fast, after, sweep=Sweep(line, area.fast_start, area.fast_stop)))
            back = before if line < area.lines else area.fast_start
            legs.append(Leg(RETRACE, fast, back, retrace))
        elif k % 2 == 0:
            legs.append(Leg(SWEEP, fast, after, sweep=Sweep(line, area.fast_start, area.fast_stop)))
        else:
            backward = Sweep(line, area.fast_stop, area.fast_start)
            legs.append(Leg(SERPENTINE_SWEEP, fast, before, sweep=backward))
    if area.serpentine:
        legs.append(Leg(RETRACE, fast, area.fast_start, retrace))
    return legs
