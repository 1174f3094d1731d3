"""`move` records (emulator/hosting/trafficlog.py) for the MP-285: the path of each run as knots
`[device time, µm]` per axis, in reported coordinates (physical minus origin), so a reader of the
traffic log (`stage-emu plot`) knows where the stage was. Built only while a traffic log is kept.

A run's axes follow trapezoids (emulator/motion.py, MP-45): knots at the start, the ends of the
ramps and the end, a linear reading between them within the ramps' rounding. Sequential axis motion
(MP-43) gives each axis its own start offset. A halt, a stop or a ROE turn is a single knot.
"""

from __future__ import annotations

from typing import Any

from emulator.devices.mp285.motion import Motion, Stage, Xyz
from protocols import mp285 as proto


def run_record(motion: Motion, stage: Stage) -> dict[str, Any]:
    path: dict[str, list[list[float]]] = {}
    start = motion.start
    reported = stage.reported(motion.p0)
    for axis, p0, delta, (offset, profile), factor in zip(
        proto.AXES, reported, motion.delta, motion.profiles, stage.factors, strict=True
    ):
        knots = [[round(start, 6), round(p0 / factor, 4)]]
        path[axis] = knots
        if not delta or profile is None or profile.duration == 0:
            continue  # this axis does not move (MP-40: speed 0 never starts)
        begin = start + offset
        ramp = profile.ramp_time
        for at in sorted({0.0, ramp, profile.duration - ramp, profile.duration}):
            position = p0 + delta * profile.fraction(at)
            knot = [round(begin + at, 6), round(position / factor, 4)]
            if knot != knots[-1]:
                knots.append(knot)
    return {"ev": "move", "t": start, "path": path}


def rest_record(t: float, physical: Xyz, stage: Stage) -> dict[str, Any]:
    """The axes stand at `physical` from `t` on (a run halted or stopped, a ROE turn)."""
    reported = stage.reported(physical)
    path = {
        axis: [[round(t, 6), round(p / factor, 4)]]
        for axis, p, factor in zip(proto.AXES, reported, stage.factors, strict=True)
    }
    return {"ev": "move", "t": t, "path": path}
