"""Motion commands (§6.2…§6.5): moves, HERE/ZERO/HOME, SPIN, VECTOR, HALT, MOTCTRL and the status reads."""

from __future__ import annotations

from emulator.devices.ms2000.activity import Activity
from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Reply,
    first_error,
    number,
)
from emulator.devices.ms2000.commands.base import CommandSet
from emulator.devices.ms2000.modules.capabilities import FocusScore
from emulator.devices.ms2000.status import right_char, status_byte
from protocols.ms2000 import ErrorCode, Kind
from protocols.rounding import round_half_away

#: SPIN takes DAC values −128…128 (MS-71)
SPIN_DAC = 128


class MotionCommands(CommandSet):
    def move(self, call: Call) -> Reply:
        """MOVE (MS-51, MS-25, MS-96 bit 4)."""
        picked = self._axis_items(call)
        self.controller.start_moves([(a, a.counts_of_units(number(i))) for a, i in picked], call.now)
        return self._move_reply(call, [a for a, _ in picked])

    def movrel(self, call: Call) -> Reply:
        """MOVREL: adds to the target, quantised to whole counts (MS-45, MS-51)."""
        picked = self._axis_items(call)
        controller = self.controller
        goals = [
            (a, controller.relative_goal(a, number(i) / a.s.unit_multiplier, call.now)) for a, i in picked
        ]
        controller.last_relative = [(a.letter, number(i)) for a, i in picked]
        controller.start_moves(goals, call.now)
        return self._move_reply(call, [a for a, _ in picked])

    def _move_reply(self, call: Call, axes: list[Axis]) -> Reply:
        controller = self.controller
        if controller.card.vb_flags & 16:
            return self._list(call, [controller.where(a.target_units()) for a in axes])
        return controller.ack()

    def here(self, call: Call) -> Reply:
        """HERE: redefine positions by moving the origin; nothing moves (MS-69)."""
        for axis, item in self._axis_items(call):
            axis.sample(call.now)
            axis.origin = (
                axis.s.polarity * axis.pos(call.now) / axis.counts_per_mm
                - number(item) / axis.s.unit_multiplier
            )
        self.controller.positions_changed()  # the origin moved: saved like a rest (MS-111)
        return self.controller.ack()

    def zero(self, call: Call) -> Reply:
        """ZERO: every axis reads 0; items are ignored (MS-70)."""
        self.controller.zero_all(call.now)
        return self.controller.ack()

    def home(self, call: Call) -> Reply:
        """HOME: towards HM, stopping at the first limit (MS-67)."""
        picked = self._axis_items(call)
        goals = [(a, a.auto.home * a.counts_per_mm) for a, _ in picked]
        self.controller.start_moves(goals, call.now, Activity.HOME)
        return self.controller.ack()

    def spin(self, call: Call) -> Reply:
        """SPIN: open-loop at n × D mm/s, clamped to the maximum (MS-71)."""
        picked = self._axis_items(call)
        codes = [ErrorCode.OUT_OF_RANGE for _, i in picked if not -SPIN_DAC <= number(i) <= SPIN_DAC]
        first_error(codes)
        for axis, item in picked:
            if not axis.enabled:
                continue
            self.controller.leave_group(axis)
            speed = max(-axis.max_speed, min(axis.max_speed, number(item) * axis.s.dac))
            axis.reset_extremes(call.now)
            axis.spin(call.now, speed)
        return self.controller.ack()

    def vector(self, call: Call) -> Reply:
        """VECTOR: constant velocity with AC ramps (MS-72)."""

        def start(axis: Axis, value: float) -> None:
            if axis.enabled:
                self.controller.leave_group(axis)
                axis.vector(call.now, max(-axis.max_speed, min(axis.max_speed, value)))

        return self._settings(call, self._per_axis(lambda a: a.velocity_cmd, start))

    def halt(self, call: Call) -> Reply:
        """HALT / `\\`: `:N-21` if a commanded move was stopped (MS-76)."""
        busy = self.controller.halt_all(call.now)
        return self.controller.error(ErrorCode.HALTED) if busy else self.controller.ack()

    def motctrl(self, call: Call) -> Reply:
        """MOTCTRL: `+` enable, `-` disable, `?` as `:A 1 0 …` (MS-75)."""
        controller = self.controller
        picked = self._axis_items(call)
        values = []
        for axis, item in picked:
            if item.kind is Kind.QUERY:
                values.append("1" if axis.enabled else "0")
            elif item.kind is Kind.PLUS or (item.kind is Kind.SET and number(item) != 0):
                controller.enable_motor(axis, call.now)
            elif item.kind in (Kind.MINUS, Kind.SET):
                controller.disable_motor(axis, call.now)
        return self._list(call, values) if values else controller.ack()

    def where(self, call: Call) -> Reply:
        """WHERE: measured positions, hardware order, VB Z decimals (MS-47, MS-77)."""
        picked = self._axis_items(call)
        for axis, _ in picked:
            axis.sample(call.now)
        return self._list(call, [self.controller.where(a.units(call.now)) for a, _ in picked])

    def rdstat(self, call: Call) -> Reply:
        """RDSTAT: status byte, or `?` N/B, `-` left and `+` right status character (MS-81)."""
        controller = self.controller
        t = call.now
        values = []
        for axis, item in self._axis_items(call):
            if item.kind is Kind.QUERY:
                values.append("B" if axis.busy(t) else "N")
            elif item.kind is Kind.MINUS:
                values.append(controller.left_char(axis, t))
            elif item.kind is Kind.PLUS:
                values.append(right_char(axis, t))
            else:
                values.append(str(status_byte(axis, t, controller.knobs.status_bit5_up_is_one)))
        return self._list(call, values)

    def rdsbyte(self, call: Call) -> Reply:
        """RDSBYTE: `:A` and one raw status byte per axis (MS-82)."""
        controller = self.controller
        raw = bytes(
            status_byte(a, call.now, controller.knobs.status_bit5_up_is_one)
            for a, _ in self._axis_items(call)
        )
        prefix = b":A " if controller.knobs.rb_space_after_ack else b":A"
        return Reply((prefix + raw,))

    def rdadc(self, call: Call) -> Reply:
        """RDADC: joystick ADCs 128 + round(127 d), Z the focus score (AUTOFOCUS, else 0), F 0
        (MS-117)."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        jx, jy = self.controller.joystick
        scorer = self.controller.modules.get(FocusScore)
        score = scorer.focus_score(call.now) if scorer is not None else None
        readings = {
            "X": 128 + round_half_away(127 * jx),
            "Y": 128 + round_half_away(127 * jy),
            "Z": score if score is not None else 0,  # MS-117: 0 without AUTOFOCUS
            "F": 0,
        }
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in readings
        ]
        first_error(codes)
        letters = {i.letter for i in items}
        return self._list(call, [str(readings[k]) for k in "XYZF" if k in letters])
