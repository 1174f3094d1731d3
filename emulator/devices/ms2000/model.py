"""The ASI MS-2000 controller model (sans-I/O, emulator/device.py).

This file wires the parts together and owns what they share: time (the scheduler), the axes and the
move groups with their completion effects, manual inputs, output and the host's line settings. The
parts are collaborators, each given the controller as a narrow Protocol of what it uses, declared in
its own file: the command line in interpreter.py (`InterpreterOwner`), power, reset and flash in
power.py (`PowerOwner`), the control channel in controls.py (`ControlsOwner`), command handlers in
commands/ (`CommandsOwner`), low-level frames in lowlevel.py (`LowLevelOwner`), reports in info.py
(`Reported`), buttons in buttons.py (`ButtonsOwner`), TTL in ttl.py (`TtlOwner`), the serial line in
serial_line.py (`LineOwner`). Axes see the controller as an `AxisOwner` (axis_owner.py) and firmware
modules as a `ModuleOwner` (modules/owner.py); modules are reached only through `self.modules`, a
ModuleSet (modules/moduleset.py), by events and capability queries.

While explaining (a traffic log is kept) the interpreter and the low-level decoder note each unit of
input, `_receive` notes garbled and silenced input, and `send_raw` summarises each output with the
command it answers.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, TypeVar

from emulator.device import (
    GARBLED,
    LOST,
    MAIN,
    REPLY,
    UNSOLICITED,
    Device,
    DeviceServices,
    Emission,
    HostLine,
    LineSettings,
    ModemLines,
)
from emulator.devices.ms2000.activity import LOWER, UPPER, Activity, MoveGroup
from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.buttons import TTL_ENABLE_BIT, Buttons
from emulator.devices.ms2000.calls import Rendered, Reply
from emulator.devices.ms2000.commands import BaseCommands
from emulator.devices.ms2000.controls import Controls
from emulator.devices.ms2000.interpreter import Interpreter
from emulator.devices.ms2000.lowlevel import LowLevel
from emulator.devices.ms2000.modules import Handler, channels_of
from emulator.devices.ms2000.modules.capabilities import FocusAxisSelect, ReportAxes
from emulator.devices.ms2000.modules.events import Event, Halt, In0Edge, MoveComplete, Zeroing
from emulator.devices.ms2000.modules.moduleset import ModuleSet
from emulator.devices.ms2000.movelog import path_record
from emulator.devices.ms2000.power import Power
from emulator.devices.ms2000.scheduler import Scheduler, Timer
from emulator.devices.ms2000.schema import Ms2000Config, baud_of
from emulator.devices.ms2000.serial_line import SerialLine, garble
from emulator.devices.ms2000.settings import CardAuto
from emulator.devices.ms2000.ttl import BASE_OUT_MODES, Ttl
from emulator.profiles.profile import Profile
from protocols import ms2000 as proto
from protocols.ms2000 import Shape
from protocols.rounding import round_half_away

T = TypeVar("T")

ERROR_LOG_SIZE = 64
TRAJECTORY_SIZE = 500
#: joystick dead band (MS-83)
DEAD_BAND = 0.02


class Ms2000Device(Device):
    def __init__(
        self, name: str, profile: Profile[Ms2000Config], now: float, services: DeviceServices
    ) -> None:
        super().__init__(name, profile, now, services)
        self.cfg = profile.config
        self.knobs = self.cfg.knobs
        self.servo_s = self.cfg.servo_ms / 1000
        self.scheduler = Scheduler()
        self.power = Power(self)
        self.axes = [
            Axis(
                self,
                i,
                letter,
                self.cfg.axes[letter],
                self.power.factory_axis(letter),
                self.power.factory_auto(letter),
                now,
            )
            for i, letter in enumerate(self.cfg.motor_axes)
        ]
        self.card = self.power.factory_card()
        self.card_auto = CardAuto()
        self.modules = ModuleSet(self, self.cfg.modules)
        self._catch_up = self.modules.catch_up_hooks()
        self.ttl = Ttl(self)
        self.buttons = Buttons(self)
        self.low = LowLevel(self)
        self.base_table = BaseCommands(self).table()
        handlers = {**self.base_table, **self.modules.handlers()}
        self.shapes = dict(proto.QUERY_SHAPES)
        self.shapes.update(self.modules.query_shapes())
        self.interpreter = Interpreter(self, self.modules.guarded(handlers))
        self.finish_pending = self.interpreter.release  # ModuleOwner: a module's late reply (MS-33)
        self.controls = Controls(self)
        self.error_log: deque[int] = deque(maxlen=ERROR_LOG_SIZE)
        self.trajectory_log: deque[str] = deque(maxlen=TRAJECTORY_SIZE)
        self.moves = 0
        self.dip = {f"sw{n}": getattr(self.cfg.dip_switches, f"sw{n}") for n in range(1, 9)}
        self.baud = baud_of(self.dip["sw4"], self.dip["sw5"])
        self.joystick = (0.0, 0.0)
        self.log_since = now
        self.user_counter = 0
        self.lcd_text: str | None = None
        self.lcd_inches = False
        self.ensync_level = 0
        self.az_fail: set[str] = set()
        self.last_relative: list[tuple[str, float | None]] = []
        self.booted_at = now
        self.line = SerialLine(self)
        self.channels = channels_of(self.cfg)  # `aux` with TTL REPORT (MS-TTLREP-1)
        self.power.power_up(now, cold=True)

    # ---- Device contract: time ----------------------------------------------------------------

    def _advance(self, now: float) -> None:
        self.scheduler.run_due(now)
        for catch_up in self._catch_up:
            catch_up(now)
        if self.power.positions_dirty:
            self.power.persist_idle_positions(now)

    def next_deadline(self) -> float | None:
        return self.scheduler.next_due()

    def at(self, due: float, action: Callable[[float], None]) -> Timer:
        return self.scheduler.at(due, action)

    def push_event(self, event: dict[str, Any]) -> None:
        self._events.append(event)

    # ---- ModuleOwner: the modules among themselves (events.py, capabilities.py) -------------------

    def emit(self, event: Event) -> None:
        self.modules.emit(event)

    def module(self, kind: type[T]) -> T | None:
        return self.modules.get(kind)

    def modules_of(self, kind: type[T]) -> tuple[T, ...]:
        return self.modules.all_of(kind)

    # ---- the line (MS-1…MS-12, MS-119) --------------------------------------------------------

    def line_settings(self, channel: str = MAIN) -> LineSettings:
        return self.line.own()

    def line_changed(self, host: HostLine | None, now: float, channel: str = MAIN) -> None:
        if channel == MAIN:  # the auxiliary port only transmits, at the main port's settings (MS-5)
            self.line.host_changed(host)

    def declare_host(self, settings: dict[str, Any]) -> None:
        self.line.declare(settings)

    def host_line(self) -> HostLine | None:
        return self.line.host()

    def garbles(self) -> bool:
        return self.line.garbles()

    def mismatch_effect(self, host: HostLine, channel: str = MAIN) -> str:
        if channel != MAIN:
            return "the auxiliary port sends at the main port's settings regardless (MS-5)"
        return self.line.mismatch_effect(host)

    def modem_lines(self, channel: str = MAIN) -> ModemLines:
        # MS-1: CTS and DSR are never asserted; nothing drives CD or RI either [choice], on either port
        return ModemLines()

    def _receive(self, data: bytes, now: float, channel: str) -> None:
        if channel != MAIN:
            if self.notes.on:
                self.notes.rx(now, LOST, data, "the auxiliary port only transmits (MS-TTLREP-1)", channel)
            return
        if self.interpreter.silenced:
            if self.notes.on:
                self.notes.rx(now, LOST, data, "silent after SP (MS-113)")
            return
        garbled = self.garbles()
        if garbled:
            data = self._garble_in(data, now)
        self.interpreter.feed(data, now, garbled)
        self.scheduler.run_due(now)
        if self.power.positions_dirty:
            self.power.persist_idle_positions(now)

    # ---- Device contract: control channel, non-volatile memory ----------------------------------

    def observe(self, name: str, now: float) -> Any:
        return self.controls.observe(name, now)

    def snapshot(self, now: float) -> dict[str, Any]:
        return self.controls.snapshot(now)

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        result = self.controls.control_input(name, params, now)
        self.scheduler.run_due(now)
        return result

    def control_names(self) -> dict[str, list[str]]:
        return self.controls.names()

    def shut_down(self, now: float) -> None:
        self.power.save_resting_positions(now)

    def forget_nonvolatile(self) -> None:
        self.power.forget()

    def positions_changed(self) -> None:
        """Something moved positions or their origin: save them at the next rest (MS-111)."""
        self.power.positions_dirty = True

    def limits_changed(self) -> None:
        """Limits changed outside SL/SU (SEARCH INDEX, DLED maxima): remembered at once (MS-65)."""
        self.power.save_auto()

    # ---- output -------------------------------------------------------------------------------

    def error(self, code: int) -> Reply:
        return Reply.text(proto.error_reply(code))

    def ack(self) -> Reply:
        return Reply.text(proto.ack(self.knobs.ack_trailing_space))

    def base_handler(self, key: str) -> Handler:
        return self.base_table[key]

    def render(self, key: str, shape: Shape | None = None) -> Rendered:
        """How to print a reply of command `key`: its query shape after `reply_shape_overrides`
        (MS-35…MS-38) unless the reply form has a fixed `shape`."""
        if shape is None:
            overrides = self.knobs.reply_shape_overrides
            shape = Shape(overrides[key]) if key in overrides else self.shapes.get(key, Shape.A_AXIS)
        return Rendered(shape, self.knobs.reply_trailing_space, self.card.vb_decimals)

    def send_raw(self, data: bytes, t: float, to: str | None = None, channel: str = MAIN) -> None:
        """Send bytes at `t` on `channel` (a line mismatch garbles only the main port's): the reply
        to the command `to` (its description while explaining, any string otherwise), or unsolicited."""
        kind = REPLY if to is not None else UNSOLICITED
        summary = None
        if self.notes.on:
            summary = f"{proto.shown(data)} ({'unsolicited' if to is None else 'reply to ' + to})"
        if channel == MAIN and self.garbles():
            data = garble(data)
            kind = GARBLED
            if summary is not None:
                sides = self.line.describe_mismatch()
                summary = f"garbled: {sides} the host reads {proto.shown(data)} of {summary} (MS-4)"
        self._outbox.append(Emission(t, data, channel, kind, summary))

    def _garble_in(self, data: bytes, t: float) -> bytes:
        """MS-4: what the controller reads of bytes a mismatched host sent."""
        junk = garble(data)
        if self.notes.on:
            sides = self.line.describe_mismatch()
            summary = f"garbled: {sides} the device reads {data.hex(' ')} as {junk.hex(' ')} (MS-4)"
            self.notes.rx(t, GARBLED, junk, summary)
        return junk

    def unsolicited(self, text: str, t: float) -> None:
        """An unsolicited line with the current terminator (MS-18, MS-96)."""
        self.send_raw(proto.frame([text.encode("latin-1")], bool(self.card.vb_flags & 8)), t)

    def where(self, units: float) -> str:
        return proto.where(units, self.card.vb_decimals)

    # ---- error log (MS-41) --------------------------------------------------------------------

    def log_error(self, code: int) -> None:
        self.error_log.append(int(code))

    def record_sample(self, axis: Axis, t: float) -> None:
        """A DUMP trajectory sample at each leg boundary (MS-108)."""
        velocity = axis.traj.vel(t)
        vmax = axis.max_speed * axis.counts_per_mm
        dac = 128 + round(127 * max(-1.0, min(1.0, velocity / vmax))) if vmax else 128
        ms = round_half_away((t - self.booted_at) * 1000)
        self.trajectory_log.append(f"{ms} {axis.letter} {axis.target} {round_half_away(axis.pos(t))} {dac}")

    def path_changed(self, axis: Axis, t: float) -> None:
        """A `move` record (movelog.py), built only while a traffic log is kept."""
        if self.notes.on:
            self.push_event(path_record(axis, t))

    # ---- axes and moves -----------------------------------------------------------------------

    def axis_named(self, letter: str) -> Axis | None:
        return next((a for a in self.axes if a.letter == letter), None)

    def focus_axis(self) -> Axis | None:
        """The axis ZS, the TTL Z-stack step (MS-94) and CRISP move: CRISP's `UL F` index, else Z."""
        selector = self.modules.get(FocusAxisSelect)
        index = selector.focus_index() if selector is not None else None
        return self.axes[index] if index is not None and index < len(self.axes) else self.axis_named("Z")

    def relative_goal(self, axis: Axis, delta_mm: float, t: float) -> float:
        """R: the current target plus the distance quantised to whole counts (MS-45, MS-51). Manual
        motion, SPIN and VE have no target: the move they end starts from the actual position (MS-71)."""
        open_ended = axis.activity in (Activity.MANUAL, Activity.SPIN, Activity.VELOCITY)
        base = round_half_away(axis.pos(t)) if open_ended else axis.target
        return base + round_half_away(axis.s.polarity * delta_mm * axis.counts_per_mm)

    def start_moves(
        self, goals: list[tuple[Axis, float]], t: float, activity: Activity = Activity.MOVE
    ) -> None:
        """Start a commanded move of several axes together (MS-51, MS-52, MS-64)."""
        group = MoveGroup[Axis](activity)
        for axis, goal in goals:
            if not axis.enabled:
                continue
            self.leave_group(axis)
            axis.group = group
            group.axes.add(axis)
            axis.reset_extremes(t)
            axis.move_to(t, goal, activity)
        if group.axes:
            self.moves += 1

    def start_scan_move(self, axis: Axis, goal: float, t: float, speed_mm_s: float | None = None) -> None:
        """A SCAN leg (MS-SCAN-4): busy like homing (one leg, right status character `B`, no OUT0
        pulse). The leg is planned at once, so `speed_mm_s` stands in for `S` only meanwhile."""
        speed = axis.s.speed
        if speed_mm_s is not None:
            axis.s.speed = speed_mm_s
        try:
            self.start_moves([(axis, goal)], t, Activity.HOME)
        finally:
            axis.s.speed = speed

    def leave_group(self, axis: Axis) -> None:
        if axis.group is not None:
            axis.group.axes.discard(axis)
            axis.group = None

    def axis_finished(self, axis: Axis, t: float) -> None:
        group = axis.group
        axis.group = None
        if group is None:
            return
        group.axes.discard(axis)
        group.landed.append(axis.letter)
        if not group.axes:
            self._move_complete(group, t)

    def _move_complete(self, group: MoveGroup[Axis], t: float) -> None:
        self.push_event(
            {
                "ev": "move_complete",
                "t": t,
                "positions": {a.letter: self.where(a.units(t)) for a in self.axes},
            }
        )
        if self.card.vb_flags & 1:
            self.unsolicited("N", t)
        if self.card.vb_flags & 32:
            self.unsolicited(":A " + " ".join(self.where(a.units(t)) for a in self.axes), t)
        if group.activity is Activity.MOVE:
            self.ttl.pulse(t)
        self.modules.emit(MoveComplete(t, tuple(group.landed)))

    def halt_all(self, t: float) -> bool:
        """Stop every motion and module activity (MS-76); True if a commanded move was running."""
        busy = any(a.busy(t) for a in self.axes)
        for axis in self.axes:
            self.leave_group(axis)
            axis.stop(t)
        self.modules.emit(Halt(t))
        return busy

    def zero_all(self, t: float) -> None:
        """ZERO (MS-70): every axis reads 0, nothing moves."""
        self.modules.emit(Zeroing(t))
        for axis in self.axes:
            axis.sample(t)
            axis.origin += axis.user_mm(t)
        self.positions_changed()  # the origin moved: saved like a rest (MS-111)

    def move_all_to_zero(self, t: float) -> None:
        self.start_moves([(a, a.counts_of(0.0)) for a in self.axes], t)

    def enable_motor(self, axis: Axis, t: float) -> None:
        if not axis.enabled:
            axis.stop(t)
        axis.enabled = True

    def disable_motor(self, axis: Axis, t: float) -> None:
        self.leave_group(axis)
        axis.stop(t)
        axis.enabled = False

    def set_manual_enabled(self, axis: Axis, enabled: bool, t: float) -> None:
        axis.s.manual_enabled = enabled
        if not enabled and axis.activity is Activity.MANUAL:
            axis.stop(t)

    # ---- manual inputs (MS-83, MS-84) ---------------------------------------------------------

    @property
    def button_held_ms(self) -> float:
        return self.buttons.held_ms

    @property
    def joystick_fast(self) -> bool:
        return self.buttons.fast

    def manual_inverted(self, axis: Axis) -> bool:
        switch = {2: "sw8", 3: "sw7"}.get(axis.s.input_device)
        return switch is not None and self.dip[switch] == "down"

    def joystick_velocity(self, axis: Axis) -> float:
        deflection = {2: self.joystick[0], 3: self.joystick[1]}.get(axis.s.input_device, 0.0)
        if abs(deflection) < DEAD_BAND or not axis.s.manual_enabled:
            return 0.0
        if self.manual_inverted(axis):
            deflection = -deflection
        share = self.card.js_fast if self.buttons.fast else self.card.js_slow
        return deflection * share / 100 * axis.max_speed

    def resume_manual(self, axis: Axis, t: float) -> None:
        velocity = self.joystick_velocity(axis)
        if velocity:
            axis.manual(t, velocity)

    def set_joystick(self, x: float, y: float, t: float) -> None:
        self.joystick = (x, y)
        for axis in self.axes:
            if axis.s.input_device in (2, 3):
                axis.manual(t, self.joystick_velocity(axis))

    def turn_wheel(self, counts: float, t: float) -> None:
        if self.modules.wheel(counts, t):
            return  # CRISP's lock offset took the turn (MS-CRISP-6)
        ratio = 1.0 if self.buttons.fast else self.card.js_slow / self.card.js_fast
        um = counts * self.cfg.wheel_um_per_count * self.card.js_wheel / 100 * ratio
        for axis in self.axes:
            if axis.s.input_device == 22 and axis.s.manual_enabled:
                axis.nudge(t, axis.s.polarity * um / 1000 * axis.counts_per_mm)

    # ---- status characters (MS-81) ------------------------------------------------------------

    def left_char(self, axis: Axis, t: float) -> str:
        if axis.at_limit(t, UPPER):
            return "U"
        if axis.at_limit(t, LOWER):
            return "L"
        if not axis.enabled:
            return "D"
        return self.buttons.left_char(t) or " "

    def busy(self, t: float) -> bool:
        return any(a.busy(t) for a in self.axes)

    # ---- TTL and ENSYNC -----------------------------------------------------------------------

    def out0_modes(self) -> set[int]:
        return set(BASE_OUT_MODES) | self.modules.out0_modes()

    def in0_available(self, mode: int) -> bool:
        return self.modules.in0_available(mode)

    def in0_edge(self, t: float) -> None:
        """A rising edge on IN0 (MS-90, MS-SEQ-2); BE bit 4 disables the TTL inputs (MS-86)."""
        if self.card.button_enable & TTL_ENABLE_BIT:
            self.in0_function(self.card.ttl_in, t)
            self.modules.emit(In0Edge(t))

    def in0_function(self, mode: int, t: float) -> None:
        self.modules.in0_trigger(mode, t)

    def refresh_out0(self, t: float) -> None:
        self.ttl.refresh(t)

    def toggle_out0(self, t: float) -> None:
        self.ttl.toggle(t)

    def ensync_toggle(self) -> None:
        self.ensync_level ^= 1

    def report_axes(self) -> list[Axis]:
        """Axes reported by IN0 mode 5: a module's selection (RING BUFFER's `RM Y`, MS-RB-4) or all."""
        selector = self.modules.get(ReportAxes)
        if selector is None:
            return list(self.axes)
        mask = selector.report_mask()
        return [a for a in self.axes if mask & (1 << a.index)]
