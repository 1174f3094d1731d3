"""PEDALS: foot pedals that move the focus axis (§9.14, MS-PEDAL-1, MS-PEDAL-2).

`PEDAL X=step_mm Y=rate Z=multiplier` (shortcut `PD`): a tap (a press shorter than 300 ms) moves the
focus axis one step up or down when the pedal is released; a longer press moves it at `rate` mm/s
(clamped to the axis maximum) for as long as the pedal is held. `Z` is the integer multiplier for
zoom axes, stored only (no profile has a zoom axis). Pedal motion is manual: never busy. The values
are volatile (§9.14 does not mark them `SS Z`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.device import ControlError
from emulator.devices.ms2000.activity import Activity
from emulator.devices.ms2000.calls import Call, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel
from emulator.devices.ms2000.modules.events import Halt, Reset, on
from protocols.ms2000 import Fmt

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

#: MS-PEDAL-1 defaults: 1 µm per tap [choice], 1 mm/s, multiplier 1
FACTORY = {"step_mm": 0.001, "rate": 1, "multiplier": 1}
#: presses shorter than this are taps (MS-PEDAL-2)
TAP_MS = 300.0
#: a press longer than an hour is a mistake
MAX_PRESS_MS = 3_600_000.0
DIRECTION = {"up": 1, "down": -1}


@register
class Pedals(Module, ControlChannel):
    name = "PEDALS"
    inputs = frozenset({"pedal"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.values = dict(FACTORY)
        self._release: Timer | None = None

    def handlers(self) -> dict[str, Handler]:
        return {"PD": self.pedal}

    def pedal(self, call: Call) -> Reply:
        """PEDAL X=step (mm) Y=rate (integer mm/s) Z=multiplier (MS-PEDAL-1); ranges [choice]."""
        values = self.values

        def setter(key: str, cast: type) -> Any:
            return lambda v: values.__setitem__(key, cast(v))

        params = {
            "X": Param(lambda: values["step_mm"], setter("step_mm", float), within(0.000001, 10), Fmt.F6),
            "Y": Param(lambda: values["rate"], setter("rate", int), within(1, 100, integer=True)),
            "Z": Param(lambda: values["multiplier"], setter("multiplier", int), within(1, 100, integer=True)),
        }
        return run_settings(call, params, "XYZ", self.controller.render(call.key), self.controller.ack())

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.values = dict(FACTORY)
        self._cancel_release()

    @on(Halt)
    def halt(self, event: Halt) -> None:
        self._cancel_release()

    def _cancel_release(self) -> None:
        if self._release is not None:
            self._release.cancel()
            self._release = None

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`pedal {which: up|down, ms}`: press now, release `ms` later (MS-PEDAL-2)."""
        which = params.get("which")
        if which not in DIRECTION:
            raise ControlError(f"pedal: which must be 'up' or 'down', got {which!r}")
        ms = params.get("ms", 100.0)
        if isinstance(ms, bool) or not isinstance(ms, int | float) or not 0 <= ms <= MAX_PRESS_MS:
            raise ControlError(f"pedal: ms must be a number in 0…{MAX_PRESS_MS:g}, got {ms!r}")
        axis = self.controller.focus_axis()
        if axis is None or not axis.s.manual_enabled:
            return False
        sign = DIRECTION[which] * axis.s.polarity
        self._cancel_release()
        if ms < TAP_MS:
            step = sign * self.values["step_mm"] * axis.counts_per_mm
            self._release = self.controller.at(now + ms / 1000, lambda due: self._tap(axis, step, due))
        else:
            axis.manual(now, sign * min(float(self.values["rate"]), axis.max_speed))
            self._release = self.controller.at(now + ms / 1000, lambda due: self._let_go(axis, due))
        return True

    def _tap(self, axis: Axis, step_counts: float, t: float) -> None:
        self._release = None
        axis.nudge(t, step_counts)

    def _let_go(self, axis: Axis, t: float) -> None:
        self._release = None
        if axis.activity is Activity.MANUAL:
            axis.manual(t, 0.0)
