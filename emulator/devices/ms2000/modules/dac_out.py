"""DAC OUT: the general-purpose 16-bit, 0–10 V output on header SV1 pin 5 (§9.7, MS-DAC-1…MS-DAC-3).

`WRDAC X=volts` sets it (outside 0–10 V `:N-4`); the output is quantised to 16 bits and read on the
control channel as `dac_out_v`; `WRDAC X?` answers the volts as set, value first (`X=1.100000 :A`).
It starts at 0 V and is not saved. In piezo builds (build name containing `PZ`) the DAC drives the
focus axis: `WRDAC` is refused and the output follows the focus axis across its travel.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import Call, CommandError, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment
from emulator.devices.ms2000.modules.events import Reset, on
from protocols.ms2000 import ErrorCode, Fmt
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner

FULL_SCALE_V = 10.0
TOP_CODE = 65535  # 16 bits
#: builds whose DAC drives a piezo focus axis (MS-DAC-3)
PIEZO_MARK = "PZ"


def code_of(volts: float) -> int:
    """The DAC code for a voltage (MS-DAC-1): round(volts / 10 × 65535), clamped to the range."""
    return max(0, min(TOP_CODE, round_half_away(volts / FULL_SCALE_V * TOP_CODE)))


def volts_of(code: int) -> float:
    return code * FULL_SCALE_V / TOP_CODE


@register
class DacOut(Module, LcdSegment, ControlChannel):
    name = "DAC OUT"
    observable = "dac_out_v"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.volts = 0.0

    @property
    def drives_piezo(self) -> bool:
        return PIEZO_MARK in self.controller.cfg.build_name

    def handlers(self) -> dict[str, Handler]:
        return {"WRDAC": self.wrdac}

    def wrdac(self, call: Call) -> Reply:
        """WRDAC X=0…10 volts; `X?` the volts as set (MS-DAC-1, MS-DAC-2); refused in PZ builds."""
        if self.drives_piezo:
            raise CommandError(ErrorCode.FAILED)  # MS-DAC-3 [choice: :N-5]
        params = {"X": Param(lambda: self.volts, self._set, within(0.0, FULL_SCALE_V), Fmt.F6)}
        return run_settings(call, params, "X", self.controller.render(call.key), self.controller.ack())

    def _set(self, volts: float) -> None:
        self.volts = volts

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.volts = 0.0  # not saved: 0 V at power-up and reset [choice, MS-DAC-1]

    def _piezo_volts(self, axis: Axis, now: float) -> float:
        """The focus axis's physical position scaled from its travel onto 0–10 V (MS-DAC-3)."""
        low, high = axis.cfg.travel_mm
        machine_mm = axis.physical(now) / axis.counts_per_mm
        return (machine_mm - low) / (high - low) * FULL_SCALE_V

    def output_volts(self, now: float) -> float:
        focus = self.controller.focus_axis()
        volts = self._piezo_volts(focus, now) if self.drives_piezo and focus is not None else self.volts
        return volts_of(code_of(volts))

    def observe(self, now: float) -> Any:
        return self.output_volts(now)

    def lcd_segment(self, now: float) -> str | None:
        return f"D {self.output_volts(now):.1f}"  # §9.0 [choice]
