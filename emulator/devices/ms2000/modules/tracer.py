"""TRACER: the G-code path-following build (§9.11, MS-TRACER-1…MS-TRACER-6).

A `_TRACER` build is a standard controller (MS-TRACER-1) plus what Tracer Console relies on:
- 115200 baud (DIP 4 and 5 DOWN); at any other rate the controller still works and observable
  `tracer` reads `{"ready": false}` so that client tools can refuse to run (MS-TRACER-2);
- M03/M05 are the base `TTL Y=1`/`TTL Y=0` on OUT0: nothing of the module's own (MS-TRACER-3);
- the analog BNC maps the focus (Z) position between the soft limits `SL Z` (min) and `SU Z` (max)
  onto 0–10 V, observable `analog_out_v`; knob `tracer_analog_polarity` picks the direction
  (MS-TRACER-4, a [conflict]).
Tracer mode and its binary stream are not emulated: those bytes are ordinary input (MS-TRACER-6).
The G-code interpreter itself is host-side, in protocols/clients/gcode.py (MS-TRACER-5).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel
from emulator.profiles.schema import Choice, Field

#: MS-TRACER-2: the only rate Tracer Console runs at
TRACER_BAUD = 115200
#: MS-TRACER-4: full scale of the analog BNC
FULL_SCALE_V = 10.0


def analog_volts(z_mm: float, low_mm: float, high_mm: float, polarity: str) -> float:
    """MS-TRACER-4: Z in [low, high] onto 0–10 V, rising with Z (`increasing`, the document's
    equation V = 0.1·Z + 5 for ±50 µm) or falling (`decreasing`, its prose); clamped outside."""
    if high_mm <= low_mm:  # no range to map: the output rests at 0 V [choice]
        return 0.0
    share = min(1.0, max(0.0, (z_mm - low_mm) / (high_mm - low_mm)))
    if polarity == "decreasing":
        share = 1.0 - share
    return FULL_SCALE_V * share


@register
class Tracer(Module, ControlChannel):
    name = "TRACER"
    knob_fields = (
        Field(
            "tracer_analog_polarity",
            Choice(("increasing", "decreasing")),
            "increasing",
            "MS-TRACER-4",
            "analog BNC voltage rises (increasing) or falls (decreasing) as Z goes from SL Z to SU Z",
        ),
    )
    observable = "tracer"

    def observe(self, now: float) -> Any:
        """MS-TRACER-2: ready only at 115200 baud (the rate read from the DIP switches at power-up)."""
        return {"ready": self.controller.baud == TRACER_BAUD}

    def observables(self) -> dict[str, Callable[[float], Any]]:
        return {**super().observables(), "analog_out_v": self.analog_out_v}

    def analog_out_v(self, now: float) -> float:
        """MS-TRACER-4: the output follows the focus axis where it is (it ramps during a move). The
        soft limits are machine positions (MS-49), so the Z compared with them is too."""
        axis = self.controller.focus_axis()
        if axis is None:
            return 0.0
        z_mm = axis.pos(now) / axis.counts_per_mm
        polarity = self.controller.knobs.tracer_analog_polarity
        return analog_volts(z_mm, axis.auto.soft_lower, axis.auto.soft_upper, polarity)
