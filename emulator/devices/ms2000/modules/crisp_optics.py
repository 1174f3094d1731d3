"""CRISP's simulated optical signal (MS-CRISP-6): the reflecting surface, its drift, the summed
detector signal and its signal-to-noise ratio, as the control input `crisp` sets them.

The surface is a place of the focus axis. It is kept in machine millimetres, so that ZERO, `H` or
a reset of the axis's coordinates do not move the sample (only the numbers the host reads change);
it is given and reported in the axis's user coordinates, in µm. Until an input places it, it sits at
the axis's user 0. Drift moves it at a constant rate, counted from the instant it was last set.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from emulator.device import ControlError
from emulator.profiles.schema import finite_number
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis

#: the focus error saturates at the ends of its 12-bit signed range (MS-CRISP-6)
ERROR_LIMIT = 2047
FACTORY_SUM = 3000.0
#: signal-to-noise ratio of a clean reflection [choice: no documented default]
FACTORY_SNR = 30.0
PARAMS = ("surface_um", "drift_um_per_s", "sum", "snr")


@dataclass
class Optics:
    #: surface in machine mm when `since`; None: at the focus axis's user 0 (not placed yet)
    machine_mm: float | None = None
    #: drift in user µm per second
    drift_um_per_s: float = 0.0
    since: float = 0.0
    sum: float = FACTORY_SUM
    snr: float = FACTORY_SNR

    def surface_um(self, axis: Axis, now: float) -> float:
        """Where the surface is now, in the axis's user µm."""
        drift_um = self.drift_um_per_s * (now - self.since)
        if self.machine_mm is None:
            return drift_um
        return axis.user_of_machine_mm(self.machine_mm) * 1000 + drift_um

    def error(self, axis: Axis, offset: int, counts_per_um: float, now: float) -> int:
        """e = clamp(round(G × (s − z)) − offset, ±2047), z the axis's physical place in user µm."""
        z_um = axis.user_mm_of(axis.physical(now)) * 1000
        raw = round_half_away(counts_per_um * (self.surface_um(axis, now) - z_um)) - offset
        return max(-ERROR_LIMIT, min(ERROR_LIMIT, raw))

    def apply(self, params: dict[str, Any], axis: Axis | None, now: float) -> dict[str, float]:
        """The control input `crisp {surface_um, drift_um_per_s, sum, snr}` (Appendix B): every
        parameter checked before any is applied."""
        unknown = sorted(set(params) - set(PARAMS))
        if unknown:
            raise ControlError(
                f"crisp: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(PARAMS)}"
            )
        for name, value in params.items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not finite_number(value):
                raise ControlError(f"crisp: {name} must be a finite number, got {value!r}")
            if name in ("sum", "snr") and value < 0:
                raise ControlError(f"crisp: {name} must not be negative, got {value!r}")
        if axis is None:
            raise ControlError("crisp: the build has no focus axis")
        surface = float(params.get("surface_um", self.surface_um(axis, now)))
        self.machine_mm = axis.machine_mm_of_user(surface / 1000)
        self.since = now
        self.drift_um_per_s = float(params.get("drift_um_per_s", self.drift_um_per_s))
        self.sum = float(params.get("sum", self.sum))
        self.snr = float(params.get("snr", self.snr))
        return self.describe(axis, now)

    def describe(self, axis: Axis | None, now: float) -> dict[str, float]:
        return {
            "surface_um": 0.0 if axis is None else self.surface_um(axis, now),
            "drift_um_per_s": self.drift_um_per_s,
            "sum": self.sum,
            "snr": self.snr,
        }
