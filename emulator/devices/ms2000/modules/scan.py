"""SCAN MODULE: raster and serpentine stage scans with SYNC and pixel-clock outputs (§9.3,
MS-SCAN-1…MS-SCAN-7).

`SN` assigns the fast and slow axes and the pattern (shared with ARRAY MODULE, scan_roles.py), `NR`
the fast-axis start, stop and encoder divide (or a pixel count), `NV` the slow-axis start, stop,
number of lines and overshoot factor; all are saved by `SS Z`. Bare `SN` (or `@` held over 1 s)
starts a scan made of moves of the motion model (scan_plan.py), busy throughout; bare `SN` or a
momentary `@` aborts it: the moving axis ramps down at its move's deceleration (state `P`) and the
scan ends where it rests, logging 86. The SYNC output (`scan_sync`) pulses as the fast axis crosses
the start of each active sweep, and with ENC_INT's counting on (`TTL X=1`) the ENCODER output gives
one pulse per `divide` counts of the active region, reported per line (`scan_pixels`); both come
only from the axis the encoder jumper selects (profile `scan_jumper_axis`). A line whose pulse count
differs from the expected one logs 85.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from emulator.device import ControlError
from emulator.devices.ms2000.buttons import EXTRA, LONG
from emulator.devices.ms2000.calls import Call, CommandError, Param, Reply, run_settings, whole, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment, PanelButtons
from emulator.devices.ms2000.modules.enc_int import COUNTING_MODE
from emulator.devices.ms2000.modules.events import Halt, MoveComplete, Reset, on
from emulator.devices.ms2000.modules.scan_plan import Leg, ScanArea, Sweep, plan
from emulator.devices.ms2000.modules.scan_roles import FAST, SERPENTINE, SLOW, shared_roles
from emulator.profiles.schema import Choice, Field
from protocols.ms2000 import ErrorCode, Fmt, Kind
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

ENC_INT = "ENC_INT"
#: MS-SCAN-2: the counter sees one edge per 4 quadrature counts and pulses at most every other one
COUNTS_PER_EDGE = 4
MIN_DIVIDE, MAX_COUNT = 8, 32767
MAX_OVERSHOOT = 100.0  # [choice]
FACTORY_RANGE: dict[str, float] = {"start": 0.0, "stop": 0.0, "divide": 24}
FACTORY_LINES: dict[str, float] = {"start": 0.0, "stop": 0.0, "lines": 1, "overshoot": 1.0}
SCAN_ABORTED, PIXELS_WRONG = 86, 85  # MS-SCAN-6
FN_SCAN = 8  # BE F function: scan start/stop (Appendix B)
IDLE, STOPPING = "I", "P"  # MS-SCAN-7 (the moving states are in scan_plan.py)


def _restored(factory: dict[str, float], data: Any) -> dict[str, float]:
    values = dict(factory)
    if isinstance(data, dict):
        for key, value in data.items():
            if key in values and isinstance(value, int | float) and not isinstance(value, bool):
                values[key] = value
    return values


@register
class ScanModule(Module, PanelButtons, LcdSegment, ControlChannel):
    name = "SCAN MODULE"
    profile_fields = (
        Field(
            "scan_jumper_axis",
            Choice(("X", "Y")),
            "X",
            "MS-SCAN-6",
            "axis whose encoder the jumpers wire to SYNC and the pixel clock (SCAN MODULE)",
        ),
    )
    button_priority = 30  # after SEQUENCER and CRISP, before ARRAY (MS-85)
    observable = "scan"
    inputs = frozenset({"scan_drop_pulses"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.roles = shared_roles(controller)
        self.range = dict(FACTORY_RANGE)  # NR
        self.lines = dict(FACTORY_LINES)  # NV
        self.state = IDLE
        self.legs: list[Leg] = []
        self.leg = 0
        self.line = 0
        self.drop_pending = 0
        self._timers: list[Timer] = []

    def handlers(self) -> dict[str, Handler]:
        return {"SN": self.scan, "NR": self.scanr, "NV": self.scanv}

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_SCAN: self.toggle}

    # ---- reports ------------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        return self.state != IDLE

    def lcd_segment(self, now: float) -> str | None:
        return self.state

    def observe(self, now: float) -> Any:
        return {
            "state": self.state,
            "line": self.line,
            "lines": int(self.lines["lines"]),
            "pixels": self.pixels(),
            "counting": self.counting(),
        }

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`scan_drop_pulses {n}`: the next n pixel pulses are lost (MS-SCAN-6)."""
        n = params.get("n")
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_COUNT:
            raise ControlError(f"scan_drop_pulses: n must be an integer 0…{MAX_COUNT}, got {n!r}")
        self.drop_pending += n
        return {"pending": self.drop_pending}

    # ---- SS Z ---------------------------------------------------------------------------------

    def save(self) -> dict[str, Any]:
        return {"range": dict(self.range), "lines": dict(self.lines), **self.roles.save()}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        self.range = _restored(FACTORY_RANGE, data.get("range"))
        self.lines = _restored(FACTORY_LINES, data.get("lines"))
        self.roles.restore(data, self.controller)

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self._finish(IDLE)
        self.drop_pending = 0

    @on(Halt)
    def halt(self, event: Halt) -> None:
        """HALT has stopped the axes: the scan ends at once (86 when one was running)."""
        if self.running:
            self.controller.log_error(SCAN_ABORTED)
        self._finish(IDLE)

    # ---- settings (MS-SCAN-1…MS-SCAN-3) ---------------------------------------------------------

    def scan(self, call: Call) -> Reply:
        """SCAN: roles and pattern; bare `SN` starts a scan or stops the running one (MS-SCAN-4);
        without exactly one fast axis `:N-5` (MS-SCAN-1)."""
        if [i for i in call.items if i.kind is not Kind.NUMBER]:
            return run_settings(
                call, self.roles.params(), "XYZF", self.controller.render(call.key), self.controller.ack()
            )
        if self.running:
            self.stop(call.now)
        elif not self.start(call.now):
            raise CommandError(ErrorCode.FAILED)
        return self.controller.ack()

    def scanr(self, call: Call) -> Reply:
        """SCANR: X start, Y stop (mm), Z divide, F pixels (replaces the stop) (MS-SCAN-2)."""
        values = self.range
        pixels: list[int] = []

        def setter(key: str) -> Callable[[float], None]:
            return lambda v: values.__setitem__(key, v)

        params = {
            "X": Param(lambda: values["start"], setter("start"), fmt=Fmt.F6),
            "Y": Param(lambda: values["stop"], setter("stop"), fmt=Fmt.F6),
            "Z": Param(lambda: values["divide"], setter("divide"), whole(MIN_DIVIDE, MAX_COUNT)),
            "F": Param(self.pixels, lambda v: pixels.append(int(v)), whole(1, MAX_COUNT)),
        }
        reply = run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())
        if pixels:  # with the start and divide of the same command, whatever the item order
            values["stop"] = values["start"] + pixels[-1] * self.divide_step() / self._counts_per_mm()
        return reply

    def scanv(self, call: Call) -> Reply:
        """SCANV: X start, Y stop (mm), Z lines, F overshoot factor (MS-SCAN-3)."""
        values = self.lines

        def setter(key: str) -> Callable[[float], None]:
            return lambda v: values.__setitem__(key, v)

        params = {
            "X": Param(lambda: values["start"], setter("start"), fmt=Fmt.F6),
            "Y": Param(lambda: values["stop"], setter("stop"), fmt=Fmt.F6),
            "Z": Param(lambda: values["lines"], setter("lines"), whole(1, MAX_COUNT)),
            "F": Param(lambda: values["overshoot"], setter("overshoot"), within(0, MAX_OVERSHOOT), Fmt.F6),
        }
        return run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())

    def divide_step(self) -> int:
        """The divide the pulses follow: a multiple of 4 counts, rounded down (MS-SCAN-2)."""
        divide = int(self.range["divide"])
        return divide - divide % COUNTS_PER_EDGE

    def _fast_axis(self) -> Axis | None:
        """The scan's fast axis; while `SN` names none, the jumper axis [choice]."""
        return self.roles.axis_with(FAST, self.controller) or self.controller.axis_named(
            self.controller.cfg.scan_jumper_axis
        )

    def _counts_per_mm(self) -> float:
        axis = self._fast_axis()
        return axis.counts_per_mm if axis is not None else self.controller.axes[0].counts_per_mm

    def pixels(self) -> int:
        """Pixels per line: floor(C × |stop − start| / divide) (MS-SCAN-2)."""
        span = abs(self.range["stop"] - self.range["start"]) * self._counts_per_mm()
        return math.floor(span / self.divide_step() + 1e-9)

    def counting(self) -> bool:
        """Pixel pulses need ENC_INT with its interrupt enabled, `TTL X=1` (MS-SCAN-4)."""
        return ENC_INT in self.controller.cfg.modules and self.controller.card.ttl_in == COUNTING_MODE

    # ---- running (MS-SCAN-4…MS-SCAN-7) ----------------------------------------------------------

    def toggle(self, now: float) -> None:
        if self.running:
            self.stop(now)
        else:
            self.start(now)

    def start(self, now: float) -> bool:
        """Plan the scan and start its first move; False without exactly one fast axis."""
        fast = self.roles.axis_with(FAST, self.controller)
        if fast is None:
            return False
        slow = self.roles.axis_with(SLOW, self.controller)
        area = ScanArea(
            self.range["start"],
            self.range["stop"],
            self.lines["start"],
            self.lines["stop"],
            int(self.lines["lines"]),
            self.lines["overshoot"],
            self.roles.pattern == SERPENTINE,
        )
        self.legs = plan(area, fast, slow)
        self.leg = -1
        self._next_leg(now)
        return True

    def stop(self, now: float) -> None:
        """Abort (MS-SCAN-5): the moving axis ramps down at its move's deceleration and the scan ends
        when it rests (state P until then), logging 86; that line logs nothing else (MS-SCAN-6)."""
        if not self.running:
            return
        self.controller.log_error(SCAN_ABORTED)
        self._cancel_timers()
        self.state = STOPPING
        if 0 <= self.leg < len(self.legs):
            self.legs[self.leg].axis.brake(now)

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` held over 1 s starts a scan on release; a press while one runs aborts it (MS-SCAN-5)."""
        if name != "at":
            return False
        if self.running:
            self.stop(now)
        elif press in (LONG, EXTRA):
            self.start(now)
        else:
            return False
        return True

    def _next_leg(self, now: float) -> None:
        self.leg += 1
        if self.leg >= len(self.legs):
            self._finish(IDLE)
            return
        leg = self.legs[self.leg]
        self.state = leg.state
        goal = float(round_half_away(leg.axis.counts_of(leg.goal_mm)))
        self.controller.start_scan_move(leg.axis, goal, now, leg.speed_mm_s)
        if leg.sweep is not None:
            self._time_sweep(leg.axis, leg.sweep, now)

    def _time_sweep(self, axis: Axis, sweep: Sweep, now: float) -> None:
        """SYNC and the line's pixel count when the fast axis crosses the active region's ends, read
        from the planned trajectory."""
        self.line = sweep.line
        begin = axis.counts_of(sweep.begin_mm)
        end = axis.counts_of(sweep.end_mm)
        at_begin = axis.traj.first_reach(begin, now)
        at_end = axis.traj.first_reach(end, at_begin if at_begin is not None else now)
        wired = axis.hw_letter == self.controller.cfg.scan_jumper_axis
        pulses = abs(round_half_away(end) - round_half_away(begin)) // self.divide_step() if wired else 0
        done = at_end if at_end is not None else axis.traj.end
        # the previous line's timers have all run by now
        self._timers = [self.controller.at(done, lambda t: self._line_end(sweep.line, pulses, t))]
        if wired and at_begin is not None:
            self._timers.append(self.controller.at(at_begin, lambda t: self._sync(sweep.line, t)))

    def _sync(self, line: int, now: float) -> None:
        self.controller.push_event({"ev": "scan_sync", "line": line, "t": now})

    def _line_end(self, line: int, pulses: int, now: float) -> None:
        """The pulses the counter saw, less any dropped; 85 when they are not the expected count."""
        if not self.counting():
            return
        dropped = min(self.drop_pending, pulses)
        self.drop_pending -= dropped
        count = pulses - dropped
        self.controller.push_event({"ev": "scan_pixels", "line": line, "count": count, "t": now})
        if count != self.pixels():
            self.controller.log_error(PIXELS_WRONG)

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        axes = event.axes
        now = event.t
        if not self.running or not 0 <= self.leg < len(self.legs):
            return
        leg = self.legs[self.leg]
        if leg.axis.letter not in axes:
            return
        if self.state == STOPPING:
            self._finish(IDLE)
        elif abs(leg.axis.pos(now) - leg.axis.counts_of(leg.goal_mm)) > 0.5:
            self.stop(now)  # stopped short at a limit or by a stall [choice]
            self._finish(IDLE)
        else:
            self._next_leg(now)

    def _cancel_timers(self) -> None:
        for timer in self._timers:
            timer.cancel()
        self._timers = []

    def _finish(self, state: str) -> None:
        self._cancel_timers()
        self.legs = []
        self.leg = 0
        self.state = state
