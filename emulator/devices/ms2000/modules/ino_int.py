"""INO_INT: the TTL IN0 interrupt service and its base modes (MS-90, MS-94).

Every IN0 mode other than 0 needs this module; it implements modes 2 (repeat the last relative
move), 4 (Z-stack step with `ZS`), 5 (asynchronous position reports every `RT X` ms) and 10 (toggle
OUT0). Other modules implement further modes (RING BUFFER mode 1, ...).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import Call, Param, Reply, one_of, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, In0Interrupt, ReportFields, TtlIn
from emulator.devices.ms2000.modules.events import In0ModeChanged, Reset, on
from protocols.ms2000 import Fmt
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

REPEAT_RELATIVE, Z_STACK, REPORT, TOGGLE_OUT = 2, 4, 5, 10
FACTORY_ZS = {"step": 0.0, "steps": 1, "mode": 0, "timeout_ms": 500}


@register
class InoInt(Module, TtlIn, In0Interrupt, ControlChannel):
    name = "INO_INT"
    in0_modes = frozenset({REPEAT_RELATIVE, Z_STACK, REPORT, TOGGLE_OUT})
    observable = "z_stack"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.zs = dict(FACTORY_ZS)
        self.start_units = 0.0
        self.index = 0
        self.direction = 1
        self.last_edge: float | None = None
        self._report: Timer | None = None
        self._report_start = 0.0

    def handlers(self) -> dict[str, Handler]:
        return {"ZS": self.zstack}

    def save(self) -> dict[str, Any]:
        return dict(self.zs)

    def restore(self, data: dict[str, Any] | None) -> None:
        self.zs = dict(FACTORY_ZS)
        for key, value in (data or {}).items():
            if key in self.zs and isinstance(value, int | float):
                self.zs[key] = value

    @on(Reset)
    def reset(self, event: Reset) -> None:
        now = event.t
        self._stop_reports()
        self._restart_stack(now)

    def observe(self, now: float) -> Any:
        return {
            **self.zs,
            "index": self.index,
            "start": self.start_units,
            "reporting": self._report is not None,
        }

    def zstack(self, call: Call) -> Reply:
        """ZS X=step (units) Y=steps Z=mode (0 sawtooth, 1 triangle) F=timeout ms (MS-94)."""
        zs = self.zs

        def setter(key: str, cast: type) -> Any:
            return lambda v: zs.__setitem__(key, cast(v))

        params = {
            "X": Param(lambda: zs["step"], setter("step", float), fmt=Fmt.F6),
            "Y": Param(lambda: zs["steps"], setter("steps", int), within(1, 65535, integer=True)),
            "Z": Param(lambda: zs["mode"], setter("mode", int), one_of(0, 1)),
            "F": Param(lambda: zs["timeout_ms"], setter("timeout_ms", int), within(0, 65535, integer=True)),
        }
        return run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())

    @on(In0ModeChanged)
    def in0_mode_changed(self, event: In0ModeChanged) -> None:
        if event.mode != REPORT:
            self._stop_reports()
        if event.mode == Z_STACK:
            self._restart_stack(event.t)

    def in0_trigger(self, mode: int, now: float) -> None:
        if mode == REPEAT_RELATIVE:
            self._repeat_relative(now)
        elif mode == Z_STACK:
            self._stack_step(now)
        elif mode == REPORT:
            if self._report is None:
                self._report_start = now
                self._report = self.controller.at(now + self._period(), self._send_report)
            else:
                self._stop_reports()
        elif mode == TOGGLE_OUT:
            self.controller.toggle_out0(now)

    # ---- mode 2 -------------------------------------------------------------------------------

    def _repeat_relative(self, now: float) -> None:
        controller = self.controller
        moves = [(controller.axis_named(letter), units) for letter, units in controller.last_relative]
        focus = controller.focus_axis()
        if not moves and focus is not None and self.zs["step"]:
            moves = [(focus, self.zs["step"])]
        goals = [
            (axis, controller.relative_goal(axis, (units or 0.0) / axis.s.unit_multiplier, now))
            for axis, units in moves
            if axis is not None
        ]
        controller.start_moves(goals, now)

    # ---- mode 4 -------------------------------------------------------------------------------

    def _restart_stack(self, now: float) -> None:
        focus = self.controller.focus_axis()
        self.start_units = focus.units(now) if focus is not None else 0.0
        self.index = 0
        self.direction = 1
        self.last_edge = None

    def _stack_step(self, now: float) -> None:
        focus = self.controller.focus_axis()
        if focus is None:
            return
        timed_out = self.last_edge is not None and (now - self.last_edge) * 1000 > self.zs["timeout_ms"]
        self.last_edge = now
        steps = int(self.zs["steps"])
        if timed_out:
            self.index = 0
            self.direction = 1
        elif self.zs["mode"] == 0:
            self.index = 0 if self.index >= steps else self.index + 1
        else:
            if self.direction > 0 and self.index >= steps:
                self.direction = -1
            elif self.direction < 0 and self.index <= 0:
                self.direction = 1
            self.index += self.direction
        goal = self.start_units + self.index * self.zs["step"]
        self.controller.start_moves([(focus, focus.counts_of_units(goal))], now)

    # ---- mode 5 -------------------------------------------------------------------------------

    def _period(self) -> float:
        return self.controller.card.rt_report_ms / 1000

    def _send_report(self, now: float) -> None:
        ms = round_half_away((now - self._report_start) * 1000)
        fields = [self.controller.where(a.units(now)) for a in self.controller.report_axes()]
        # e.g. TRACKING's PMT sum (MS-TRACK-3)
        fields += [f for m in self.controller.modules_of(ReportFields) for f in m.report_fields(now)]
        self.controller.unsolicited(" ".join([str(ms), *fields]), now)
        self._report = self.controller.at(now + self._period(), self._send_report)

    def _stop_reports(self) -> None:
        if self._report is not None:
            self._report.cancel()
            self._report = None
