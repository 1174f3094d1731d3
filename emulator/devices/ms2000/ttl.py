"""The TTL IN0/IN1 inputs and the OUT0 output (§6.7).

OUT0's level comes from its mode (`TTL Y`): 0 low, 1 high, 2 (and 8) pulses of `RT Y` ms after
each commanded move, module modes from the module (LED DIMMER's PWM in mode 9); IN0 mode 10 toggles
it whatever the mode; `TTL F=-1` inverts it (MS-91). Every edge of the effective level is pushed as
an `ttl_out0` event.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from emulator.devices.ms2000.buttons import TTL_ENABLE_BIT

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.settings import CardSettings

#: OUT0 modes of the base controller (MS-91); 8 is PREPULSE's timed pulse, emulated as mode 2
BASE_OUT_MODES = frozenset({0, 1, 2})
PULSE_MODES = frozenset({2, 8})


class TtlOwner(Protocol):
    """All the TTL lines use of their controller."""

    @property
    def card(self) -> CardSettings:
        """`TTL`, `RT Y`, `BE` and `VB` (MS-90, MS-91, MS-86, MS-96)."""

    @property
    def modules(self) -> ModuleSet:
        """What drives OUT0 in a module's mode; IN0's falling edge in a level mode."""

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def unsolicited(self, text: str, t: float) -> None: ...

    def push_event(self, event: dict[str, Any]) -> None: ...

    def in0_edge(self, t: float) -> None:
        """A rising edge on IN0: the mode's function, then the modules' `In0Edge`."""


class Ttl:
    def __init__(self, controller: TtlOwner) -> None:
        self.controller = controller
        self.in0 = 0
        self.in1 = 0
        self.raw = 0
        self.level = 0
        self._pulse: Timer | None = None
        self._in0_fall: Timer | None = None

    def reset(self, t: float) -> None:
        if self._pulse is not None:
            self._pulse.cancel()
            self._pulse = None
        self.apply_mode(t)

    def effective(self) -> int:
        driven = self.controller.modules.out0_level(self.controller.card.ttl_out)
        level = self.raw if driven is None else driven
        return level ^ (1 if self.controller.card.ttl_polarity == -1 else 0)

    def refresh(self, t: float) -> None:
        level = self.effective()
        if level != self.level:
            self.level = level
            self.controller.push_event({"ev": "ttl_out0", "level": level, "t": t})

    def set_raw(self, level: int, t: float) -> None:
        self.raw = level
        self.refresh(t)

    def apply_mode(self, t: float) -> None:
        """`TTL Y` or `TTL F` changed: mode 1 drives high, others start low."""
        self.set_raw(1 if self.controller.card.ttl_out == 1 else 0, t)

    def pulse(self, t: float) -> None:
        """End-of-move pulse in OUT0 mode 2 (MS-91)."""
        if self.controller.card.ttl_out not in PULSE_MODES:
            return
        if self._pulse is not None:
            self._pulse.cancel()
        self.set_raw(1, t)
        self._pulse = self.controller.at(t + self.controller.card.rt_pulse_ms / 1000, self._pulse_end)

    def _pulse_end(self, t: float) -> None:
        self._pulse = None
        self.set_raw(0, t)

    def toggle(self, t: float) -> None:
        """IN0 mode 10 (MS-90)."""
        self.set_raw(1 - self.raw, t)

    def pwm(self) -> float:
        duty = self.controller.modules.out0_pwm(self.controller.card.ttl_out)
        return 0.0 if duty is None else duty

    # ---- inputs --------------------------------------------------------------------------------

    def set_in0(self, level: int, t: float) -> None:
        rising = level and not self.in0
        falling = self.in0 and not level
        self.in0 = level
        if rising:
            self.controller.in0_edge(t)
        elif falling and self.controller.card.button_enable & TTL_ENABLE_BIT:
            self.controller.modules.in0_release(self.controller.card.ttl_in, t)  # level modes (MS-CRISP-7)

    def pulse_in0(self, ms: float, t: float) -> None:
        if self._in0_fall is not None:
            self._in0_fall.cancel()
        self.set_in0(1, t)
        self._in0_fall = self.controller.at(t + ms / 1000, lambda due: self.set_in0(0, due))

    def set_in1(self, level: int, t: float) -> None:
        if level == self.in1:
            return
        self.in1 = level
        if self.controller.card.vb_flags & 4:
            self.controller.unsolicited("H" if level else "L", t)
