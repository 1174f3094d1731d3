"""XY KNOBS: the two side knobs that move X and Y by hand (§9.15, MS-KNOB-1, MS-KNOB-2).

Each knob count moves its axis by speed × 0.1 µm, where the speed is `JS F` in slow mode and
`JS F` × `JS T`³ in fast mode: the joystick button's fast/slow toggle selects it. Knob motion is
manual, like the focus wheel: never busy, within the limits, and the axis's MOVREL target follows it.

`JS F` and `JS T` themselves are base settings (MS-74) and answer in every build; knob
`knob_speeds_need_module` (MS-KNOB-1) makes them `:N-2` in builds without this module.
"""

from __future__ import annotations

from typing import Any

from emulator.device import ControlError
from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel

#: one knob count at speed 1 moves 0.1 µm (MS-KNOB-2)
MM_PER_COUNT_AT_SPEED_1 = 0.0001
#: a knob input larger than this is a mistake, not a turn of a knob
MAX_COUNTS = 1e6


@register
class XyKnobs(Module, ControlChannel):
    name = "XY KNOBS"
    inputs = frozenset({"xy_knob"})

    def speed(self) -> float:
        """The knob speed value: slow F, fast F × T³ (MS-KNOB-1)."""
        card = self.controller.card
        return card.knob_slow * card.knob_mult**3 if self.controller.joystick_fast else card.knob_slow

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`xy_knob {x_counts, y_counts}` (MS-KNOB-2)."""
        unknown = set(params) - {"x_counts", "y_counts"}
        if unknown:
            raise ControlError(f"xy_knob: unknown parameter {sorted(unknown)[0]!r}; use x_counts, y_counts")
        for letter, key in (("X", "x_counts"), ("Y", "y_counts")):
            counts = params.get(key, 0)
            if isinstance(counts, bool) or not isinstance(counts, int | float) or abs(counts) > MAX_COUNTS:
                raise ControlError(f"xy_knob: {key} must be a number of counts, got {counts!r}")
            if counts:
                self._turn(letter, float(counts), now)
        return True

    def _turn(self, letter: str, counts: float, now: float) -> None:
        axis = self.controller.axis_named(letter)
        if axis is None or not axis.s.manual_enabled:
            return
        mm = counts * self.speed() * MM_PER_COUNT_AT_SPEED_1
        axis.nudge(now, axis.s.polarity * mm * axis.counts_per_mm)
