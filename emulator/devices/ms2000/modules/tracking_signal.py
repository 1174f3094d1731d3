"""The PhotoTrack quadrant PMT: what control input `pmt` puts on its four channels (MS-TRACK-3).

Two sources [choice]:
- fixed intensities `pmt {q1, q2, q3, q4}` (Appendix B): the channels read exactly these, wherever
  the stage is, so an unbalanced detector drives the stage on at a constant rate;
- a simulated object `pmt {x_um, y_um, vx_um_s, vy_um_s, sigma_um, brightness, quarter_turns}`:
  a Gaussian spot of rms radius `sigma_um` that is centred when the stage stands at (x, y) µm user
  position, drifting at (vx, vy) µm/s. Each quadrant collects the share of the spot on its side of
  both centre lines, so the normalised error is erf(offset / (σ√2)), linear near the centre and
  saturating at ±1; the detector may be mounted `quarter_turns` × 90° counter-clockwise, which
  `LK F` must match for the loop to converge.

Channel i (1–4) of a detector at rotation k lies at 45° + (i − 1 + k) × 90° from +X, counter-
clockwise. The controller, told the rotation by `LK F`, turns the channel errors back into stage
axes (`errors`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from emulator.device import ControlError

Quad = tuple[float, float, float, float]

FIXED_KEYS = ("q1", "q2", "q3", "q4")
OBJECT_KEYS = ("x_um", "y_um", "vx_um_s", "vy_um_s", "sigma_um", "brightness", "quarter_turns")
#: a PMT count larger than this is a mistake, not a signal
MAX_SIGNAL = 1e9


@dataclass(frozen=True)
class Fixed:
    """Channels that read the same whatever the stage does."""

    channels: Quad

    def read(self, stage_um: tuple[float, float], t: float) -> Quad:
        return self.channels


@dataclass(frozen=True)
class SpotObject:
    """A moving spot; positions are where the stage must stand (user µm) to centre it."""

    x_um: float
    y_um: float
    vx_um_s: float
    vy_um_s: float
    sigma_um: float
    brightness: float
    quarter_turns: int
    since: float

    def centre(self, t: float) -> tuple[float, float]:
        dt = t - self.since
        return self.x_um + self.vx_um_s * dt, self.y_um + self.vy_um_s * dt

    def read(self, stage_um: tuple[float, float], t: float) -> Quad:
        cx, cy = self.centre(t)
        px = _share(cx - stage_um[0], self.sigma_um)
        py = _share(cy - stage_um[1], self.sigma_um)
        b = self.brightness
        # the spot's share in each quadrant of the stage frame, counter-clockwise from +X+Y
        stage = (b * px * py, b * (1 - px) * py, b * (1 - px) * (1 - py), b * px * (1 - py))
        k = self.quarter_turns
        return (stage[k % 4], stage[(1 + k) % 4], stage[(2 + k) % 4], stage[(3 + k) % 4])


Source = Fixed | SpotObject

DARK = Fixed((0.0, 0.0, 0.0, 0.0))


def _share(offset_um: float, sigma_um: float) -> float:
    """The part of a Gaussian spot `offset_um` off-centre on the positive side of the centre line."""
    return 0.5 * (1 + math.erf(offset_um / (sigma_um * math.sqrt(2))))


def errors(channels: Quad, quad_order: int) -> tuple[float, float, float]:
    """(sum, ex, ey) in stage axes: the MS-TRACK-3 formulas on the channels, turned by `LK F` × 90°."""
    q1, q2, q3, q4 = channels
    total = q1 + q2 + q3 + q4
    if total <= 0:
        return 0.0, 0.0, 0.0
    ex = ((q1 + q4) - (q2 + q3)) / total
    ey = ((q1 + q2) - (q3 + q4)) / total
    for _ in range(quad_order % 4):
        ex, ey = -ey, ex  # a quarter turn counter-clockwise
    return total, ex, ey


def parse(params: dict[str, Any], previous: Source, now: float) -> Source:
    """The source a `pmt` input describes: fixed channels, or a spot (missing keys: defaults)."""
    keys = set(params)
    unknown = keys - set(FIXED_KEYS) - set(OBJECT_KEYS)
    if unknown:
        known = ", ".join((*FIXED_KEYS, *OBJECT_KEYS))
        raise ControlError(f"pmt: unknown parameter {sorted(unknown)[0]!r}; use {known}")
    if keys & set(FIXED_KEYS) and keys & set(OBJECT_KEYS):
        raise ControlError("pmt: give quadrant intensities q1…q4 or an object (x_um, …), not both")
    if not keys & set(OBJECT_KEYS):
        old = previous.channels if isinstance(previous, Fixed) else DARK.channels
        q = [_number(params, key, old[i], 0.0, MAX_SIGNAL) for i, key in enumerate(FIXED_KEYS)]
        return Fixed((q[0], q[1], q[2], q[3]))
    turns = _number(params, "quarter_turns", 0, 0, 3)
    if turns != int(turns):
        raise ControlError(f"pmt: quarter_turns must be 0, 1, 2 or 3, got {turns!r}")
    return SpotObject(
        x_um=_number(params, "x_um", 0.0, -1e6, 1e6),
        y_um=_number(params, "y_um", 0.0, -1e6, 1e6),
        vx_um_s=_number(params, "vx_um_s", 0.0, -1e6, 1e6),
        vy_um_s=_number(params, "vy_um_s", 0.0, -1e6, 1e6),
        sigma_um=_number(params, "sigma_um", 5.0, 0.01, 1e4),
        brightness=_number(params, "brightness", 1000.0, 0.0, MAX_SIGNAL),
        quarter_turns=int(turns),
        since=now,
    )


def _number(params: dict[str, Any], key: str, default: float, low: float, high: float) -> float:
    value = params.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
        raise ControlError(f"pmt: {key} must be a number in {low:g}…{high:g}, got {value!r}")
    return float(value)
