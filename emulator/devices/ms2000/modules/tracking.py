"""TRACKING: ASI PhotoTrack, the XY stage following an object seen by a quadrant PMT (§9.12).

Commands (MS-TRACK-1, MS-TRACK-2): bare `LK` toggles tracking (the `@` short press), `LK X`
calibrates (`@` long press), `LK Y` resets (`home` extra-long press), `LK Z=sum_min`, `LK F=quad
order`; `LK X?` reads the state: `I` idle, `C` calibrating, `T` tracking, `P` paused (sum below
`LK Z`), `E` error (range exceeded or calibration failed). `LR X=cal_value Y=xy_range Z=z_range
F=cal_range`, bare `LR Z` a bare multi-line report; `UL X=focus_enable Y=z_cal Z=closeness
F=focus_index`, bare `UL` stops tracking.

The loop (MS-TRACK-3) runs every 10 ms of device time while tracking or paused: it reads the PMT
(tracking_signal.py), pauses below `LK Z`, and otherwise moves X and Y by ex × cal_value µm and
ey × cal_value µm through the motion model, as manual motion (never busy: a commanded move of an
axis takes precedence over the correction for as long as it runs). Moving X or Y, or Z with focus
tracking enabled, further than the range from where tracking began stops it in state `E`.

CRISP claims the same three commands; when a build lists both, CRISP serves them (§9.0): CRISP
declares that it `outranks` TRACKING and the module set installs handlers accordingly, whatever
the profile order. Everything else of this module (`pmt`, observable, LCD segment) stays.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.buttons import EXTRA, LONG, NORMAL
from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Param,
    Reply,
    first_error,
    number,
    one_of,
    run_settings,
    within,
)
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules import tracking_signal as pmt
from emulator.devices.ms2000.modules.capabilities import (
    ControlChannel,
    LcdSegment,
    PanelButtons,
    ReportFields,
)
from emulator.devices.ms2000.modules.events import Halt, Reset, on
from protocols.ms2000 import ErrorCode, Fmt, Kind
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

IDLE, CALIBRATING, TRACKING, PAUSED, ERROR = "I", "C", "T", "P", "E"
#: MS-TRACK-3: the correction period
LOOP_S = 0.010
#: one unit of error moves the stage cal_value × this many mm per cycle (MS-TRACK-3)
MM_PER_CAL = 0.001
#: calibration [choice]: X steps +F/2, −F, +F/2, the error read after each leg has settled
CAL_LEG_S = 0.1
#: the calibrated gain nulls an offset in this many cycles [choice]
CAL_CYCLES = 10
#: a slope (error per µm) below this is no signal: the calibration fails [choice]
MIN_SLOPE = 1e-6
FACTORY: dict[str, float] = {
    "sum_min": 100,  # LK Z
    "quad_order": 0,  # LK F
    "cal_value": 1.0,  # LR X
    "xy_range": 0.5,  # LR Y, mm
    "z_range": 0.05,  # LR Z, mm
    "cal_range": 0.01,  # LR F, mm
    "focus_enable": 0,  # UL X
    "z_cal": 1.0,  # UL Y
    "closeness": 1.0,  # UL Z
    "focus_index": 2,  # UL F
}


@register
class Tracking(Module, ReportFields, PanelButtons, LcdSegment, ControlChannel):
    name = "TRACKING"
    button_priority = 25  # MS-85 does not rank it: after CRISP, before SCAN [choice]
    observable = "tracking"
    inputs = frozenset({"pmt"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.settings = dict(FACTORY)
        self.state = IDLE
        self.reason: str | None = None
        self.source: pmt.Source = pmt.DARK
        #: user mm of X, Y and the focus axis where tracking began (the ranges count from there)
        self.start: dict[str, float] = {}
        #: correction not yet moved, in counts, per axis letter (moves are whole counts)
        self.residue: dict[str, float] = {}
        self._timer: Timer | None = None

    # ---- the PMT and the loop (MS-TRACK-3) ------------------------------------------------------

    def _xy(self) -> tuple[Axis | None, Axis | None]:
        return self.controller.axis_named("X"), self.controller.axis_named("Y")

    def signal(self, now: float) -> tuple[float, float, float]:
        """(sum, ex, ey) where the stage is now."""
        x, y = self._xy()
        stage = (x.user_mm(now) * 1000 if x else 0.0, y.user_mm(now) * 1000 if y else 0.0)
        return pmt.errors(self.source.read(stage, now), int(self.settings["quad_order"]))

    def _tick(self, now: float) -> None:
        self._timer = None
        if self._out_of_range(now):
            self._enter(ERROR, now, "range")
            return
        total, ex, ey = self.signal(now)
        self._enter(PAUSED if total < self.settings["sum_min"] else TRACKING, now)
        if self.state == TRACKING:
            x, y = self._xy()
            step_mm = self.settings["cal_value"] * MM_PER_CAL
            for axis, share in ((x, ex), (y, ey)):
                if axis is not None:
                    self._move(axis, share * step_mm, now)
        self._timer = self.controller.at(now + LOOP_S, self._tick)

    def _move(self, axis: Axis, mm: float, now: float) -> None:
        """Move by `mm` (user) as manual motion, carrying the part below a count to the next cycle."""
        counts = self.residue.get(axis.letter, 0.0) + axis.s.polarity * mm * axis.counts_per_mm
        whole = round_half_away(counts)
        self.residue[axis.letter] = counts - whole
        if whole:
            axis.nudge(now, float(whole))

    def _watched(self) -> list[tuple[Axis, float]]:
        """Axes whose excursion ends tracking, with their range in mm (MS-TRACK-2)."""
        x, y = self._xy()
        watched = [(axis, self.settings["xy_range"]) for axis in (x, y) if axis is not None]
        index = int(self.settings["focus_index"])  # UL F
        if self.settings["focus_enable"] and index < len(self.controller.axes):
            watched.append((self.controller.axes[index], self.settings["z_range"]))
        return watched

    def _out_of_range(self, now: float) -> bool:
        return any(
            abs(axis.user_mm(now) - self.start.get(axis.letter, axis.user_mm(now))) > limit + 1e-9
            for axis, limit in self._watched()
        )

    # ---- states -------------------------------------------------------------------------------

    def _enter(self, state: str, now: float, reason: str | None = None) -> None:
        if state != self.state:
            self.state = state
            self.reason = reason
            event: dict[str, Any] = {"ev": "tracking", "state": state, "t": now}
            if reason:
                event["reason"] = reason
            self.controller.push_event(event)
        if state not in (TRACKING, PAUSED, CALIBRATING):
            self._cancel()

    def _cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def engage(self, now: float) -> None:
        """Start tracking from here: the ranges count from the current positions."""
        self._cancel()
        self.start = {axis.letter: axis.user_mm(now) for axis, _ in self._watched()}
        self.residue = {}
        total, _, _ = self.signal(now)
        self._enter(PAUSED if total < self.settings["sum_min"] else TRACKING, now)
        self._timer = self.controller.at(now + LOOP_S, self._tick)

    def toggle(self, now: float) -> None:
        """Bare `LK`, the `@` short press: on from idle or error, off otherwise (MS-TRACK-1)."""
        if self.state in (IDLE, ERROR):
            self.engage(now)
        else:
            self._enter(IDLE, now)

    def stop(self, now: float) -> None:
        self._enter(IDLE, now)

    def _resume_check(self, now: float) -> None:
        """The sum or its threshold changed: pause or resume at once, not at the next cycle."""
        if self.state in (TRACKING, PAUSED):
            total, _, _ = self.signal(now)
            self._enter(PAUSED if total < self.settings["sum_min"] else TRACKING, now)

    # ---- calibration (`LK X`, `@` long press) [choice] ------------------------------------------

    def calibrate(self, now: float) -> None:
        """Step X by +F/2, −F, +F/2 and set cal_value from the error's slope; no slope: `E`."""
        x, _ = self._xy()
        if x is None:
            self._enter(ERROR, now, "calibration")
            return
        self._cancel()
        self._enter(CALIBRATING, now)
        half = self.settings["cal_range"] / 2
        self.residue = {}
        self._move(x, half, now)
        self._timer = self.controller.at(now + CAL_LEG_S, lambda t: self._cal_back(x, half, t))

    def _cal_back(self, x: Axis, half: float, now: float) -> None:
        plus = self.signal(now)[1]
        self._move(x, -2 * half, now)
        self._timer = self.controller.at(now + CAL_LEG_S, lambda t: self._cal_return(x, half, plus, t))

    def _cal_return(self, x: Axis, half: float, plus: float, now: float) -> None:
        minus = self.signal(now)[1]
        self._move(x, half, now)
        self._timer = self.controller.at(now + CAL_LEG_S, lambda t: self._cal_done(plus, minus, t))

    def _cal_done(self, plus: float, minus: float, now: float) -> None:
        self._timer = None
        # the error falls as the stage moves towards +X onto the object: positive for a working loop
        slope = (minus - plus) / (self.settings["cal_range"] * 1000)  # error per µm
        cal_value = 1 / (slope * CAL_CYCLES) if slope > MIN_SLOPE else 0.0
        if not 0 < cal_value <= CAL_VALUE_MAX:
            self._enter(ERROR, now, "calibration")
            return
        self.settings["cal_value"] = cal_value
        self._enter(IDLE, now)

    # ---- commands -----------------------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        return {"LK": self.lk, "LR": self.lr, "UL": self.ul}

    def lk(self, call: Call) -> Reply:
        """LK (MS-TRACK-1): bare toggles; X calibrates, Y resets, Z/F set, X?/Z?/F?/T? read."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            self.toggle(call.now)
            return self.controller.ack()
        codes: list[int] = []
        sets: list[Callable[[], None]] = []
        actions: list[Callable[[float], None]] = []
        queries: list[Callable[[], str]] = []
        for item in items:
            letter = item.letter or ""
            if item.kind is Kind.MALFORMED:
                codes.append(ErrorCode.UNDEFINED)
            elif letter in LK_ACTIONS:
                if item.kind is Kind.QUERY and letter == "X":
                    queries.append(lambda: self.state)
                elif item.kind is Kind.BARE:
                    actions.append(getattr(self, LK_ACTIONS[letter]))
                else:
                    codes.append(ErrorCode.OUT_OF_RANGE)
            elif letter == "T":
                if item.kind is Kind.QUERY:
                    queries.append(lambda: str(round_half_away(self.signal(call.now)[0])))
                else:
                    codes.append(ErrorCode.OUT_OF_RANGE)
            elif letter in LK_SETTINGS:
                key, check = LK_SETTINGS[letter]
                if item.kind is Kind.QUERY:
                    queries.append(partial(self._integer, key))
                    continue
                try:
                    value = check(number(item))
                except CommandError as exc:
                    codes.append(exc.code)
                    continue
                sets.append(partial(self.settings.__setitem__, key, value))
            else:
                codes.append(ErrorCode.BAD_AXIS)
        first_error(codes)
        for apply in sets:
            apply()
        self._resume_check(call.now)
        for action in actions:
            action(call.now)
        if not queries:
            return self.controller.ack()
        values = [query() for query in queries]
        # a number ends with a space (as `LK Z?` in §3); the state character does not (MS-38)
        trailing = " " if values[-1].isdigit() else ""
        return Reply.text(":A " + " ".join(values) + trailing)

    def reset_tracking(self, now: float) -> None:
        """`LK Y`, the `home` extra-long press: tracking off, error cleared [choice]."""
        self.residue = {}
        self._enter(IDLE, now)

    def lr(self, call: Call) -> Reply:
        """LR (MS-TRACK-2): the tracking parameters; bare `LR Z` the report."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if len(items) == 1 and items[0].kind is Kind.BARE and items[0].letter == "Z":
            return Reply.text(*self.report(call.now))
        params = {
            letter: Param(partial(self.settings.__getitem__, key), self._setter(key), check, Fmt.F6)
            for letter, (key, check) in LR_SETTINGS.items()
        }
        return run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())

    def ul(self, call: Call) -> Reply:
        """UL (MS-TRACK-2): focus-tracking parameters; bare `UL` stops tracking."""
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            self.stop(call.now)
            return self.controller.ack()
        checks = {**UL_SETTINGS, "F": ("focus_index", within(0, len(self.controller.axes) - 1, integer=True))}
        params = {
            letter: Param(partial(self.settings.__getitem__, key), self._setter(key), check, Fmt.F6)
            for letter, (key, check) in checks.items()
        }
        return run_settings(call, params, "XYZF", self.controller.render(call.key), self.controller.ack())

    def _integer(self, key: str) -> str:
        return str(int(self.settings[key]))

    def _setter(self, key: str) -> Callable[[float], None]:
        return lambda value: self.settings.__setitem__(key, value)

    def report(self, now: float) -> list[str]:
        """Bare `LR Z` [choice of lines]."""
        s = self.settings
        total, ex, ey = self.signal(now)
        return [
            f"PhotoTrack state: {self.state}",
            f"Sum: {round_half_away(total)} min {int(s['sum_min'])}",
            f"Error X: {ex:.3f} Y: {ey:.3f}",
            f"Quad order: {int(s['quad_order'])}",
            f"Cal value: {s['cal_value']:.6f}",
            f"XY range: {s['xy_range']:.6f} mm",
            f"Z range: {s['z_range']:.6f} mm",
            f"Cal range: {s['cal_range']:.6f} mm",
            f"Focus: {'on' if s['focus_enable'] else 'off'}",
        ]

    # ---- buttons, TTL, control channel --------------------------------------------------------

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` short: toggle; `@` long: calibrate; `home` extra-long: reset (MS-TRACK-1)."""
        action = {("at", NORMAL): self.toggle, ("at", LONG): self.calibrate}.get((name, press))
        if (name, press) == ("home", EXTRA):
            action = self.reset_tracking
        if action is None:
            return False
        action(now)
        return True

    def report_fields(self, now: float) -> list[str]:
        """IN0 mode 5 reports end with the PMT sum (MS-TRACK-3)."""
        return [str(round_half_away(self.signal(now)[0]))]

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`pmt {q1…q4}` or a simulated object (tracking_signal.py)."""
        self.source = pmt.parse(params, self.source, now)
        self._resume_check(now)
        return self.observe(now)

    def lcd_segment(self, now: float) -> str | None:
        return f"{self.state} {round_half_away(self.signal(now)[0])}"  # §9.0 [choice]

    def observe(self, now: float) -> Any:
        total, ex, ey = self.signal(now)
        x, y = self._xy()
        stage = (x.user_mm(now) * 1000 if x else 0.0, y.user_mm(now) * 1000 if y else 0.0)
        return {
            "state": self.state,
            "reason": self.reason,
            "sum": total,
            "ex": ex,
            "ey": ey,
            "channels": list(self.source.read(stage, now)),
            "settings": dict(self.settings),
        }

    # ---- life cycle and SS Z ------------------------------------------------------------------

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self._cancel()
        self.state = IDLE
        self.reason = None
        self.residue = {}

    @on(Halt)
    def halt(self, event: Halt) -> None:
        """HALT stops tracking and calibration (MS-76)."""
        now = event.t
        self.stop(now)

    def save(self) -> dict[str, Any]:
        return dict(self.settings)

    def restore(self, data: dict[str, Any] | None) -> None:
        self.settings = dict(FACTORY)
        for key, value in (data or {}).items():
            if key in self.settings and isinstance(value, int | float) and not isinstance(value, bool):
                self.settings[key] = value


#: LR X range [choice]
CAL_VALUE_MAX = 100.0
#: `LK` letters that act when bare (X? reads the state)
LK_ACTIONS = {"X": "calibrate", "Y": "reset_tracking"}
#: `LK` settings: letter -> (setting, check) [choice ranges]
LK_SETTINGS: dict[str, tuple[str, Callable[[float], float]]] = {
    "Z": ("sum_min", within(0, 65535, integer=True)),
    "F": ("quad_order", within(0, 3, integer=True)),
}
LR_SETTINGS: dict[str, tuple[str, Callable[[float], float]]] = {
    "X": ("cal_value", within(0, CAL_VALUE_MAX)),
    "Y": ("xy_range", within(0.001, 100)),
    "Z": ("z_range", within(0.0001, 10)),
    "F": ("cal_range", within(0.0001, 1)),
}
UL_SETTINGS: dict[str, tuple[str, Callable[[float], float]]] = {
    "X": ("focus_enable", one_of(0, 1)),
    "Y": ("z_cal", within(-1000, 1000)),
    "Z": ("closeness", within(0, 100)),
}
