"""LED DIMMER: PWM brightness on TTL OUT0 (§9.8, MS-LED-1…MS-LED-3).

`LED X=pct` (0–100) sets the duty; `Y`, `Z`, `F` drive the extra lamp outputs with an intensity
0–100 (non-zero is on, as Micro-Manager's ASIStage LED device opens them with `LED Y=<intensity>`).
The PWM reaches OUT0 only in OUT0 mode 9 (`TTL Y=9`), where `TTL Y=9 <n>` also sets the duty.
Queries reply value first: `X=10 :A`. Saved with `SS Z`.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import Call, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment, TtlOut
from emulator.devices.ms2000.modules.events import TtlTrailingValue, on
from emulator.profiles.schema import Choice, Field
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner

PWM_MODE = 9
FACTORY = {"X": 0, "Y": 0, "Z": 0, "F": 0}
FULL = 100  # percent; every channel takes 0…100 (MS-LED-1)


@register
class LedDimmer(Module, TtlOut, LcdSegment, ControlChannel):
    name = "LED DIMMER"
    knob_fields = (
        Field(
            "ttl_pwm_trailing_value",
            Choice(("apply", "ignore")),
            "apply",
            "MS-LED-3",
            "`TTL Y=9 <n>` also sets LED X=n (LED DIMMER)",
        ),
    )
    out0_modes = frozenset({PWM_MODE})
    observable = "led"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.values = dict(FACTORY)

    def handlers(self) -> dict[str, Handler]:
        return {"LED": self.led}

    def led(self, call: Call) -> Reply:
        """LED X=0…100 duty, Y/Z/F intensities 0…100 (MS-LED-1, MS-LED-2)."""
        values = self.values
        now = call.now

        def setter(letter: str) -> Any:
            def store(value: float) -> None:
                values[letter] = int(value)
                self.controller.refresh_out0(now)

            return store

        params = {
            letter: Param(partial(values.__getitem__, letter), setter(letter), within(0, FULL, integer=True))
            for letter in "XYZF"
        }
        return run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())

    @on(TtlTrailingValue)
    def ttl_trailing_value(self, event: TtlTrailingValue) -> None:
        value, apply = event.value, self.controller.knobs.ttl_pwm_trailing_value == "apply"
        if event.out_mode == PWM_MODE and apply and 0 <= value <= FULL:
            self.values["X"] = round_half_away(value)

    def out0_level(self) -> int | None:
        return 1 if self.values["X"] > 0 else 0

    def out0_pwm(self) -> float | None:
        return float(self.values["X"])

    def lcd_segment(self, now: float) -> str | None:
        return f"L {self.values['X']}"

    def observe(self, now: float) -> Any:
        return {"x": self.values["X"], "y": self.values["Y"], "z": self.values["Z"], "f": self.values["F"]}

    def save(self) -> dict[str, Any]:
        return dict(self.values)

    def restore(self, data: dict[str, Any] | None) -> None:
        self.values = dict(FACTORY)
        for key, value in (data or {}).items():
            if key in self.values and isinstance(value, int):
                self.values[key] = value
