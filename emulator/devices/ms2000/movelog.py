"""`move` records (emulator/hosting/trafficlog.py): an axis's planned path each time it changes, so a reader
of the traffic log (`stage-emu plot`) knows where the stage was without re-parsing host commands.

Built only while a traffic log is kept (`Ms2000Device.path_changed`). The path is the axis's
trajectory from now on as knots `[device time, µm]` at its segment boundaries, in user coordinates
(polarity and origin applied, as `W` reports them); between knots a reader interpolates linearly,
which is exact for constant-velocity stretches and within the ramp's rounding elsewhere. An
open-ended motion (spin, VE, joystick) ends in `cruise`: µm/s after the last knot.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis


def path_record(axis: Axis, t: float) -> dict[str, Any]:
    traj = axis.traj
    letter = axis.letter

    def um(counts: float) -> float:
        return round(axis.user_mm_of(counts) * 1000, 4)

    knots = [[round(t, 6), um(traj.pos(t))]]
    record: dict[str, Any] = {"ev": "move", "t": t, "path": {letter: knots}}
    for seg in traj.segments:
        if seg.t1 <= t:
            continue
        if seg.t0 > t:
            _add(knots, seg.t0, um(seg.x0))
        if not math.isfinite(seg.duration):
            velocity = axis.s.polarity * seg.v0 / axis.counts_per_mm * 1000
            record["cruise"] = {letter: round(velocity, 4)}
            break
        _add(knots, seg.t1, um(seg.x1))
    return record


def _add(knots: list[list[float]], t: float, um: float) -> None:
    """A knot after the others; one at the same instant as the last (a zero-length segment) is
    left out."""
    at = round(t, 6)
    if at > knots[-1][0]:
        knots.append([at, um])
