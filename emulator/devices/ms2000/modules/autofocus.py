"""AUTOFOCUS: video autofocus scans of the focus axis (§9.6, MS-AF-1…MS-AF-8).

`AF` sets the scan (speed, range, mode, hill offset; saved by `SS Z`) and bare `AF` runs one: the
focus axis moves down by half the range, scans up through it at the set speed while the focus value
(autofocus_curve.py, control input `focus`) is sampled once per video frame, and goes to where the
filtered value was highest (hill-detect mode stops the scan early once past the hill). The reply
comes when the axis has arrived (MS-33). Too little contrast returns to the start (300), an open
clutch (302) or a run beyond the 200 µm safety limit (148) is refused, each `:N-5`. `AFC` sets the
minimum contrast, frame offset and axis, and bare `AFC` calibrates `AFADJ` with three scans.
`@`, IN0 mode 3 (an edge), IN0 mode 103 (every `RT X` ms) and `AM X=1` (after each XY move) start
runs without a reply; OUT0 mode 10 is high from a successful run to the start of the next. `RA Z`
and the LCD segment `FV nnnn` show the filtered value.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

from emulator.device import AF_SAMPLE, ControlError
from emulator.devices.ms2000.buttons import EXTRA, NORMAL
from emulator.devices.ms2000.calls import Call, CommandError, Pending, Reply
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.autofocus_curve import (
    FILTER_FRAMES,
    FRAME_S,
    Adjust,
    FocusCurve,
    FocusScan,
    frame_of,
    gain_for,
    next_frame_at,
    zero_for,
)
from emulator.devices.ms2000.modules.autofocus_settings import HILL_MODE, AfSettings
from emulator.devices.ms2000.modules.capabilities import (
    ControlChannel,
    FocusScore,
    LcdSegment,
    PanelButtons,
    TtlIn,
    TtlOut,
)
from emulator.devices.ms2000.modules.events import (
    Halt,
    In0ModeChanged,
    MoveComplete,
    Out0ModeChanged,
    Reset,
    on,
)
from emulator.profiles.schema import Bool, Field
from protocols.ms2000 import ErrorCode, Kind, Shape, error_reply
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

AUTOFOCUS, CRISP = "AUTOFOCUS", "CRISP"
AF_EDGE, AF_REPEAT = 3, 103  # IN0 modes (MS-90)
FOCUSED_OUT = 10  # OUT0 mode (MS-91)
FN_AUTOFOCUS, FN_CALIBRATE = 9, 10  # BE F functions (Appendix B)
NO_CONTRAST, CLUTCH_OPEN, SAFETY_LIMIT = 300, 302, 148  # MS-AF-4, MS-AF-5
SAFETY_MM = 0.2  # MS-AF-5
CAL_SCANS = 3  # MS-AF-6
DESCEND, SCAN, RETURN = "descend", "scan", "return"
#: events of each run (docs/ms2000.md §12) and the `result` of `af_end`
RUN_START, RUN_END = "af_start", "af_end"
FOCUSED, CALIBRATED, LOW_CONTRAST = "focused", "calibrated", "no_contrast"
HALTED, TAKEN_OVER, DROPPED = "halted", "interrupted", "dropped"


@dataclass
class Run:
    """One autofocus run or calibration in progress."""

    calibrating: bool
    serial: bool
    start_mm: float
    bottom_mm: float
    top_mm: float
    speed_mm_s: float
    scans_left: int
    #: AFADJ before a calibration, back in force if it fails or is cut short
    adjust_before: Adjust
    phase: str = DESCEND
    scan: FocusScan = field(default_factory=FocusScan)
    leg_target: int = 0
    reply: Reply | None = None
    focused: bool = False
    result: str = DROPPED


@register
class Autofocus(Module, FocusScore, TtlIn, TtlOut, PanelButtons, LcdSegment, ControlChannel):
    name = AUTOFOCUS
    knob_fields = (
        Field("af_reply_value", Bool(), False, "MS-AF-3", "a successful `AF` replies `:A <peak value>`"),
    )
    in0_modes = frozenset({AF_EDGE, AF_REPEAT})
    out0_modes = frozenset({FOCUSED_OUT})
    button_priority = 50  # MS-85: after ARRAY, before PLANAR CORRECTION
    inputs = frozenset({"focus", "clutch"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.curve = FocusCurve()
        self.clutch_engaged = True
        #: MS-DAC-3: PZ builds drive a piezo focus axis
        self.settings = AfSettings(piezo="PZ" in controller.cfg.build_name)
        self.run: Run | None = None
        self.focused = False
        self.last_max = 0
        self.start_units = 0.0
        self.final_units = 0.0
        self._reply: Reply | None = None
        self._sampler: Timer | None = None
        self._repeat: Timer | None = None

    def handlers(self) -> dict[str, Handler]:
        table: dict[str, Handler] = {
            "AF": self.afocus,
            "AFC": self.afcalib,
            "AFADJ": self.afadj,
            "AFINFO": self.afinfo,
            "AM": self.afmove,
        }
        # AL is CRISP's too; the reference does not say who wins, so the first listed serves it
        if next(n for n in self.controller.cfg.modules if n in (AUTOFOCUS, CRISP)) == AUTOFOCUS:
            table["AL"] = self.aflim
        return table

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_AUTOFOCUS: self._start_silent, FN_CALIBRATE: lambda t: self._start_silent(t, True)}

    # ---- reports and inputs -------------------------------------------------------------------

    def focus_score(self, now: float) -> int | None:
        """The filtered focus value now (MS-AF-2, MS-117): the last three frames where the axis was."""
        axis = self.controller.focus_axis()
        if axis is None:
            return None
        frame = frame_of(now)
        values = []
        for k in range(frame - FILTER_FRAMES + 1, frame + 1):
            z_um = axis.user_mm_of(axis.traj.pos(k * FRAME_S)) * 1000
            values.append(self.settings.adjust.apply(self.curve.raw(z_um, k)))
        return round_half_away(sum(values) / FILTER_FRAMES)

    def lcd_segment(self, now: float) -> str | None:
        return f"FV {self.focus_score(now) or 0:4d}"

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`focus {…}` changes the curve (Appendix B); `clutch {engaged}` (MS-AF-4)."""
        if name == "focus":
            self.curve = self.curve.updated(params)
            return asdict(self.curve)
        engaged = params.get("engaged")
        if not isinstance(engaged, bool) or set(params) != {"engaged"}:
            raise ControlError(f"clutch: expected {{engaged: true|false}}, got {params!r}")
        self.clutch_engaged = engaged
        return {"engaged": engaged}

    # ---- SS Z, reset, HALT --------------------------------------------------------------------

    def save(self) -> dict[str, Any]:
        return self.settings.save()

    def restore(self, data: dict[str, Any] | None) -> None:
        self.settings.restore(data)

    @on(Reset)
    def reset(self, event: Reset) -> None:
        """Reset and power-up (MS-112): no run, OUT0 low, IN0 mode 103 re-armed if restored."""
        now = event.t
        self._cancel_sampler()
        self._push_end(now, HALTED)  # a reset stops a run as HALT does
        self.run = None  # AFADJ is what restore() brought back
        self.focused = False
        self._arm_repeat(now, self.controller.card.ttl_in == AF_REPEAT)

    @on(Halt)
    def halt(self, event: Halt) -> None:
        """HALT (MS-76) ends a run; a run waiting to reply answers `:N-21` (MS-33)."""
        now = event.t
        if self.run is not None:
            self._end(now, Reply.text(error_reply(ErrorCode.HALTED)), result=HALTED)

    # ---- settings (autofocus_settings.py) ----------------------------------------------------

    def afocus(self, call: Call) -> Reply | Pending:
        """AF: parameters (MS-AF-1); bare, a run (MS-AF-3)."""
        if not _has_items(call):
            return self._start_serial(call.now, calibrating=False)
        return self.settings.af_command(call, self.controller.render(call.key), self.controller.ack())

    def afcalib(self, call: Call) -> Reply | Pending:
        """AFC: parameters; bare, the calibration (MS-AF-6)."""
        if not _has_items(call):
            return self._start_serial(call.now, calibrating=True)
        return self.settings.calib_command(call, self.controller.render(call.key), self.controller.ack())

    def afadj(self, call: Call) -> Reply:
        return self.settings.adjust_command(call, self.controller.render(call.key), self.controller.ack())

    def aflim(self, call: Call) -> Reply:
        return self.settings.area_command(call, self.controller.render(call.key), self.controller.ack())

    def afmove(self, call: Call) -> Reply:
        return self.settings.move_command(call, self.controller.render(call.key), self.controller.ack())

    def afinfo(self, call: Call) -> Reply:
        where = self.controller.where
        return self.settings.info(self.last_max, where(self.start_units), where(self.final_units))

    # ---- what starts a run --------------------------------------------------------------------

    def _start_serial(self, now: float, calibrating: bool) -> Pending:
        code = self._start(now, calibrating, serial=True)
        if code is not None:
            raise CommandError(code)
        # HALT (or a reset) cancels the reply and with it the run
        return Pending(None, self._take_reply, cancel=lambda t: self._drop(t, HALTED))

    def _take_reply(self, now: float) -> Reply:
        reply, self._reply = self._reply, None
        return reply if reply is not None else Reply.text(error_reply(ErrorCode.FAILED))

    def _start_silent(self, now: float, calibrating: bool = False) -> None:
        self._start(now, calibrating, serial=False)

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` normal press: autofocus (MS-AF-3); home held 3 s or more: calibration (MS-AF-6)."""
        if (name, press) == ("at", NORMAL):
            self._start_silent(now)
        elif (name, press) == ("home", EXTRA):
            self._start_silent(now, calibrating=True)
        else:
            return False
        return True

    def in0_trigger(self, mode: int, now: float) -> None:
        if mode == AF_EDGE:
            self._start_silent(now)

    @on(In0ModeChanged)
    def in0_mode_changed(self, event: In0ModeChanged) -> None:
        self._arm_repeat(event.t, event.mode == AF_REPEAT)

    def _arm_repeat(self, now: float, on: bool) -> None:
        """IN0 mode 103: a run `RT X` ms after the last one ended [choice: runs never overlap]."""
        if self._repeat is not None:
            self._repeat.cancel()
            self._repeat = None
        if on:
            self._repeat = self.controller.at(
                now + self.controller.card.rt_report_ms / 1000, self._repeat_due
            )

    def _repeat_due(self, now: float) -> None:
        self._repeat = None
        if self.run is None and self._start(now, False, serial=False) is not None:
            self._arm_repeat(now, True)  # refused: try again next period

    @on(Out0ModeChanged)
    def out0_mode_changed(self, event: Out0ModeChanged) -> None:
        if event.mode == FOCUSED_OUT:
            self.focused = False  # [choice] low until the next run succeeds

    def out0_level(self) -> int | None:
        return int(self.focused)

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        axes = event.axes
        now = event.t
        axis = self.controller.focus_axis()
        run = self.run
        if run is not None and axis is not None and axis.letter in axes:
            if axis.target != run.leg_target:  # another command took the axis over [choice]
                self._end(now, Reply.text(error_reply(ErrorCode.FAILED)), result=TAKEN_OVER)
            else:
                self._leg_done(axis, run, now)
        xy = {a.letter for a in self.controller.axes[:2]}
        if self.settings.on_move["x"] and xy & set(axes) and self.run is None:
            self._start_silent(now)  # MS-AF-8

    # ---- the run (MS-AF-3…MS-AF-6) --------------------------------------------------------------

    def _start(self, now: float, calibrating: bool, serial: bool) -> int | None:
        """Start a run; the error code when it is refused."""
        axis = self.controller.focus_axis()
        if self.run is not None and axis is not None and not axis.busy(now):
            self._drop(now)  # its motion was cut short without a completion: stale
        if self.run is not None or axis is None or not axis.enabled or self.settings.af["speed"] <= 0:
            return ErrorCode.FAILED  # [choice] nothing to scan with
        half = self.settings.af["range"] / 2
        if self.settings.area["safety"] and half > SAFETY_MM + 1e-9:
            self.controller.log_error(SAFETY_LIMIT)
            return ErrorCode.FAILED
        if not self.clutch_engaged:
            self.controller.log_error(CLUTCH_OPEN)
            return ErrorCode.FAILED
        start = axis.user_mm(now)
        self.start_units = axis.units(now)
        self.run = Run(
            calibrating=calibrating,
            serial=serial,
            start_mm=start,
            bottom_mm=start - half,
            top_mm=start + half,
            speed_mm_s=self.settings.af["speed"] / 100 * axis.max_speed,
            scans_left=CAL_SCANS if calibrating else 1,
            adjust_before=self.settings.adjust,
        )
        if calibrating:
            self.settings.adjust = Adjust()  # the first scan sees the unadjusted signal
        self.focused = False
        self.controller.refresh_out0(now)
        span = {"axis": axis.letter, "start_um": round(start * 1000, 4), "range_um": round(half * 2000, 4)}
        self.controller.push_event({"ev": RUN_START, "t": now, "calibrating": calibrating, **span})
        self._leg(axis, self.run, self.run.bottom_mm, now)
        return None

    def _leg(self, axis: Axis, run: Run, goal_mm: float, now: float, speed: float | None = None) -> None:
        """A move of the run: busy like other commanded motion (`B`), no OUT0 pulse (MS-81)."""
        self.controller.start_scan_move(axis, float(round_half_away(axis.counts_of(goal_mm))), now, speed)
        run.leg_target = axis.target  # after clamping to the limits

    def _leg_done(self, axis: Axis, run: Run, now: float) -> None:
        if run.phase == DESCEND:
            run.phase = SCAN
            run.scan = FocusScan()
            self._leg(axis, run, run.top_mm, now, run.speed_mm_s)
            self._next_frame(now)
        elif run.phase == SCAN:
            self._cancel_sampler()
            self._scan_done(axis, run, now)
        else:
            self._end(now, run.reply or self.controller.ack(), run.focused, run.result)

    def _sample(self, now: float) -> None:
        """One video frame during the scan; hill-detect may end the scan here (MS-AF-3)."""
        self._sampler = None
        run, axis = self.run, self.controller.focus_axis()
        if run is None or axis is None or run.phase != SCAN:
            return
        z_um = axis.user_mm(now) * 1000
        value = self.settings.adjust.apply(self.curve.raw(z_um, frame_of(now)))
        run.scan.add(z_um, value)
        if self.controller.explain:  # per frame: for the traffic log only (`LOG_ONLY`)
            filtered = None if run.scan.current is None else round(run.scan.current, 2)
            sample = {"ev": AF_SAMPLE, "t": now, "z_um": round(z_um, 4), "value": value, "filtered": filtered}
            self.controller.push_event(sample)
        hill = self.settings.af["mode"] == HILL_MODE and not run.calibrating
        if hill and run.scan.past_hill(self.settings.af["hill"], self.settings.calib["contrast"]):
            self._scan_done(axis, run, now)
            return
        self._next_frame(now + FRAME_S / 2)

    def _next_frame(self, after: float) -> None:
        """Sample at the first video frame starting at or after `after`."""
        self._sampler = self.controller.at(next_frame_at(after), self._sample)

    def _scan_done(self, axis: Axis, run: Run, now: float) -> None:
        scan = run.scan
        run.phase = RETURN
        if scan.best is None or scan.contrast < self.settings.calib["contrast"]:
            self.controller.log_error(NO_CONTRAST)  # MS-AF-4: back to the start, :N-5
            run.reply = Reply.text(error_reply(ErrorCode.FAILED))
            run.result = LOW_CONTRAST
            self._leg(axis, run, run.start_mm, now)
            return
        if run.calibrating:
            run.scans_left -= 1
            if run.scans_left == CAL_SCANS - 1:
                self.settings.adjust = gain_for(scan.best)
            elif run.scans_left == CAL_SCANS - 2 and scan.lowest is not None:
                self.settings.adjust = zero_for(self.settings.adjust, scan.lowest)
            if run.scans_left:
                run.phase = DESCEND
                self._leg(axis, run, run.bottom_mm, now)
                return
            self.settings.area.update(x=80, y=50)  # [choice] no image: the factory highlighted area
            run.adjust_before = self.settings.adjust
            run.result = CALIBRATED
            self._leg(axis, run, run.start_mm, now)
            return
        self.last_max = round_half_away(scan.best)
        run.focused = True
        run.result = FOCUSED
        if self.controller.knobs.af_reply_value:
            run.reply = self.controller.render("AF", Shape.A_LIST).items([("", str(self.last_max))])
        self._leg(axis, run, scan.best_um / 1000, now)

    def _end(self, now: float, reply: Reply, focused: bool = False, result: str = DROPPED) -> None:
        """The run is over: OUT0 mode 10 high if it found focus (MS-AF-8), the serial reply."""
        run = self.run
        if run is None:
            return
        axis = self.controller.focus_axis()
        if axis is not None:
            self.final_units = axis.units(now)
        self._drop(now, result)
        self.focused = focused
        self.controller.refresh_out0(now)
        if self.controller.card.ttl_in == AF_REPEAT:
            self._arm_repeat(now, True)
        if run.serial:
            self._reply = reply
            self.controller.finish_pending(now)

    def _drop(self, now: float, result: str = DROPPED) -> None:
        """Forget the run (its motion, if any, is the caller's business); a calibration cut short
        leaves AFADJ as it was."""
        self._cancel_sampler()
        if self.run is not None and self.run.calibrating:
            self.settings.adjust = self.run.adjust_before
        self._push_end(now, result)
        self.run = None

    def _push_end(self, now: float, result: str) -> None:
        """`af_end`: how the run ended and the peak of its last scan."""
        run = self.run
        if run is None:
            return
        best, best_um = run.scan.best, run.scan.best_um
        peak = {} if best is None else {"peak": round(best, 2), "peak_um": round(best_um, 4)}
        end = {"ev": RUN_END, "t": now, "result": result, "calibrating": run.calibrating}
        self.controller.push_event(end | peak)

    def _cancel_sampler(self) -> None:
        if self._sampler is not None:
            self._sampler.cancel()
            self._sampler = None


def _has_items(call: Call) -> bool:
    return any(i.kind is not Kind.NUMBER for i in call.items)
