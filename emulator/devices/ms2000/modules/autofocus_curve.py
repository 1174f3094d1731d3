"""AUTOFOCUS's simulated video focus signal and the bookkeeping of one focus scan (MS-AF-2,
MS-AF-3, MS-AF-6).

The sample under the objective gives a focus value that peaks where it is in focus: a Gaussian
hill over a baseline plus Gaussian noise (control input `focus`). The video electronics sample it
once per frame; the controller's adjustments (`AFADJ`) scale and offset it into 0…2047, and the
"filtered" value is the mean of the last three samples. Noise is a function of the seed and the
frame number only, so a run repeated at the same device times sees the same samples, however often
`RA Z` was read in between.
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

from emulator.device import ControlError
from protocols.rounding import round_half_away

#: one video frame (MS-AF-2)
FRAME_S = 1 / 30
#: samples averaged into the filtered value (MS-AF-2)
FILTER_FRAMES = 3
#: the largest focus value, a saturated signal (MS-AF-2)
SATURATED = 2047
#: [choice] the filtered peak calibration aims for: three quarters of the scale leaves headroom
CAL_TARGET = 1500


def frame_of(t: float) -> int:
    """The video frame running at device time `t` (frames start at device time 0)."""
    return math.floor(t / FRAME_S + 1e-9)


def next_frame_at(t: float) -> float:
    """When the first frame starting at or after `t` starts."""
    return math.ceil(t / FRAME_S - 1e-9) * FRAME_S


@dataclass(frozen=True)
class FocusCurve:
    """Control input `focus` (Appendix B): the focus value the sample gives at each focus position."""

    peak_um: float = 0.0
    width_um: float = 5.0
    amplitude: float = 1000.0
    baseline: float = 50.0
    noise: float = 0.0
    seed: int = 0

    def raw(self, z_um: float, frame: int) -> float:
        """The unadjusted value at focus position `z_um` (user µm) in video frame `frame`."""
        value = self.baseline + self.amplitude * math.exp(-(((z_um - self.peak_um) / self.width_um) ** 2) / 2)
        if self.noise:
            value += random.Random(f"{self.seed}:{frame}").gauss(0.0, self.noise)
        return value

    def updated(self, params: dict[str, Any]) -> FocusCurve:
        """This curve with the given parameters changed; the others keep their values."""
        changes: dict[str, Any] = {}
        for key, value in params.items():
            if key == "seed":
                if isinstance(value, bool) or not isinstance(value, int):
                    raise ControlError(f"focus: seed must be an integer, got {value!r}")
            elif key in ("peak_um", "width_um", "amplitude", "baseline", "noise"):
                if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                    raise ControlError(f"focus: {key} must be a finite number, got {value!r}")
                if key == "width_um" and value <= 0:
                    raise ControlError(f"focus: width_um must be > 0, got {value!r}")
                if key == "noise" and value < 0:
                    raise ControlError(f"focus: noise must be >= 0, got {value!r}")
                value = float(value)
            else:
                known = "peak_um, width_um, amplitude, baseline, noise, seed"
                raise ControlError(f"focus: unknown parameter {key!r}; use {known}")
            changes[key] = value
        return replace(self, **changes)


@dataclass(frozen=True)
class Adjust:
    """`AFADJ X=zero Y=amplitude Z=gain` (MS-AF-7), applied as MS-AF-2 says."""

    zero: int = 50
    amplitude: int = 100
    gain: int = 0

    def apply(self, raw: float) -> int:
        scaled = raw * self.amplitude / 100 * 2**self.gain + (self.zero - 50)
        return max(0, min(SATURATED, round_half_away(scaled)))


@dataclass
class FocusScan:
    """The filtered values met along one scan: the highest and where it was, the lowest, the first.

    A filtered value belongs to the mean position of its three samples [choice: the emulator has
    no video lag, so the peak found is the curve's peak, not one a frame behind it]."""

    window: deque[tuple[float, int]] = field(default_factory=lambda: deque(maxlen=FILTER_FRAMES))
    first: float | None = None
    best: float | None = None
    best_um: float = 0.0
    lowest: float | None = None
    current: float | None = None

    def add(self, z_um: float, value: int) -> None:
        self.window.append((z_um, value))
        if len(self.window) < FILTER_FRAMES:
            return
        filtered = sum(v for _, v in self.window) / FILTER_FRAMES
        self.current = filtered
        if self.first is None:
            self.first = filtered
        if self.best is None or filtered > self.best:
            self.best = filtered
            self.best_um = sum(z for z, _ in self.window) / FILTER_FRAMES
        if self.lowest is None or filtered < self.lowest:
            self.lowest = filtered

    @property
    def contrast(self) -> float:
        """Highest minus lowest filtered value (MS-AF-4); 0 before any."""
        return 0.0 if self.best is None or self.lowest is None else self.best - self.lowest

    def past_hill(self, offset_pct: float, min_contrast: float) -> bool:
        """MS-AF-3 hill-detect: the value rose and has now fallen below
        peak − offset % × (peak − first). The rise must reach the minimum contrast first [choice],
        so that noise on a flat stretch is not taken for a hill."""
        if self.first is None or self.best is None or self.current is None:
            return False
        rise = self.best - self.first
        if rise <= 0 or rise < min_contrast:
            return False
        return self.current < self.best - offset_pct / 100 * rise


def gain_for(peak: float) -> Adjust:
    """Calibration after its first scan (MS-AF-6) [choice]: the largest gain and then the
    amplitude that bring the unadjusted peak `peak` nearest `CAL_TARGET` without passing it."""
    gain = 0
    while gain < 3 and peak * 2 ** (gain + 1) <= CAL_TARGET:
        gain += 1
    amplitude = 100 if peak <= 0 else round_half_away(100 * CAL_TARGET / (peak * 2**gain))
    return Adjust(50, max(1, min(100, amplitude)), gain)


def zero_for(adjust: Adjust, lowest: float) -> Adjust:
    """Calibration after its second scan (MS-AF-6) [choice]: the zero that moves the background
    (the lowest filtered value met) as near 0 as the 0…100 range allows."""
    return replace(adjust, zero=max(0, min(100, round_half_away(adjust.zero - lowest))))
