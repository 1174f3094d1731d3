"""Settings commands (§6.2, §6.3, §6.6, §6.8): per-axis mechanics and servo values, soft limits and
home, manual input, joystick speeds, RTIME, ENSYNC, CUSTOMA, STOPBITS and VB."""

from __future__ import annotations

from collections.abc import Callable

from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.calls import (
    NUMBER_LIMIT,
    PSEUDO_ORDER,
    SILENT,
    Call,
    CommandError,
    Param,
    Reply,
    one_of,
    within,
)
from emulator.devices.ms2000.commands.base import CommandSet
from protocols.ms2000 import ErrorCode, Fmt, Kind, f6, integer
from protocols.rounding import round_half_away

#: UM 0 is refused (MS-44); so are values too small to keep positions finite [choice]
MIN_UNIT_MULTIPLIER = 0.001


def _positive(value: float) -> float:
    if value <= 0:
        raise CommandError(ErrorCode.OUT_OF_RANGE)
    return value


def _non_negative(value: float) -> float:
    if value < 0:
        raise CommandError(ErrorCode.OUT_OF_RANGE)
    return value


class SettingsCommands(CommandSet):
    def speed(self, call: Call) -> Reply:
        """SPEED: clamped to the axis maximum, ≤ 0 refused (MS-54)."""

        def check(axis: Axis, value: float) -> float:
            return min(_positive(value), axis.max_speed)

        return self._settings(
            call, self._per_axis(lambda a: a.s.speed, lambda a, v: setattr(a.s, "speed", v), check)
        )

    def accel(self, call: Call) -> Reply:
        """ACCEL: integer ms, 1–10000 (MS-55)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.accel_ms,
                lambda a, v: setattr(a.s, "accel_ms", int(v)),
                lambda a, v: within(1, 10000, integer=True)(v),
                Fmt.I,
            ),
        )

    def wait(self, call: Call) -> Reply:
        """WAIT: ms after landing, 0–65535 (MS-56)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.wait_ms,
                lambda a, v: setattr(a.s, "wait_ms", int(v)),
                lambda a, v: within(0, 65535, integer=True)(v),
                Fmt.I,
            ),
        )

    def backlash(self, call: Call) -> Reply:
        """BACKLASH (MS-57)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.backlash,
                lambda a, v: setattr(a.s, "backlash", v),
                lambda a, v: _non_negative(v),
            ),
        )

    def overshoot(self, call: Call) -> Reply:
        """OS: stored as whole encoder counts, reported as counts / C (MS-58)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.overshoot_counts / a.counts_per_mm,
                lambda a, v: setattr(a.s, "overshoot_counts", int(v * a.counts_per_mm)),
                lambda a, v: _non_negative(v),
            ),
        )

    def error(self, call: Call) -> Reply:
        """ERROR (drift error): values ≤ 0 are acknowledged and ignored (MS-59)."""

        def store(axis: Axis, value: float) -> None:
            if value > 0:
                axis.s.drift_error = value

        return self._settings(call, self._per_axis(lambda a: a.s.drift_error, store))

    def pcros(self, call: Call) -> Reply:
        """PCROS (finish error, MS-60)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.finish_error,
                lambda a, v: setattr(a.s, "finish_error", v),
                lambda a, v: _positive(v),
            ),
        )

    def maintain(self, call: Call) -> Reply:
        """MAINTAIN: 0, 1, 2, 3 or 5 (MS-61)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.maintain,
                lambda a, v: setattr(a.s, "maintain", int(v)),
                lambda a, v: one_of(0, 1, 2, 3, 5)(v),
                Fmt.I,
            ),
        )

    def runaway(self, call: Call) -> Reply:
        """RUNAWAY (MS-62)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.runaway, lambda a, v: setattr(a.s, "runaway", v), lambda a, v: _positive(v)
            ),
        )

    def gain(self, name: str, call: Call) -> Reply:
        """KP, KI, KD, KV, KA: stored signed integers (MS-97)."""
        return self._settings(
            call,
            self._per_axis(
                lambda a: getattr(a.s, name),
                lambda a, v: setattr(a.s, name, int(v)),
                lambda a, v: within(-32768, 32767, integer=True)(v),
                Fmt.I,
            ),
        )

    def aa(self, call: Call) -> Reply:
        """AA: 0–99, saved at once (MS-97)."""

        def store(axis: Axis, value: float) -> None:
            axis.auto.aa = int(value)
            self.controller.power.save_auto()

        return self._settings(
            call,
            self._per_axis(lambda a: a.auto.aa, store, lambda a, v: within(0, 99, integer=True)(v), Fmt.I),
        )

    def dack(self, call: Call) -> Reply:
        """DACK: mm/s per DAC count, used by SPIN (MS-71, MS-97)."""
        return self._settings(
            call,
            self._per_axis(lambda a: a.s.dac, lambda a, v: setattr(a.s, "dac", v), lambda a, v: _positive(v)),
        )

    def counts(self, call: Call) -> Reply:
        """CNTS: encoder counts per mm; the stage stops where it is physically (MS-45)."""
        controller = self.controller

        def store(axis: Axis, value: float) -> None:
            t = call.now
            controller.leave_group(axis)
            axis.stop(t)
            ratio = value / axis.counts_per_mm
            position = round_half_away(axis.pos(t) * ratio)
            axis.traj = axis.traj.rest(t, float(position))
            axis.target = position
            axis.s.overshoot_counts = int(axis.s.overshoot_counts * ratio)
            axis.s.counts_per_mm = value

        return self._settings(
            call, self._per_axis(lambda a: a.counts_per_mm, store, lambda a, v: within(1, NUMBER_LIMIT)(v))
        )

    def epolarity(self, call: Call) -> Reply:
        """EPOLARITY: ±1; −1 reverses the sign of the encoder reading (MS-97)."""

        def store(axis: Axis, value: float) -> None:
            t = call.now
            user = axis.user_mm(t)
            axis.s.polarity = int(value)
            axis.origin = axis.user_mm(t) + axis.origin - user

        return self._settings(
            call, self._per_axis(lambda a: a.s.polarity, store, lambda a, v: one_of(1, -1)(v), Fmt.I)
        )

    def unit_multiplier(self, call: Call) -> Reply:
        """UM: units per mm, sign reverses commanded and reported positions, 0 refused (MS-44)."""

        def check(axis: Axis, value: float) -> float:
            if abs(value) < MIN_UNIT_MULTIPLIER:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.unit_multiplier, lambda a, v: setattr(a.s, "unit_multiplier", v), check
            ),
        )

    def lladdr(self, call: Call) -> Reply:
        """LLADDR: low-level axis ids 1–254 (MS-114)."""

        def store(axis: Axis, value: float) -> None:
            axis.s.ll_id = int(value)
            self.controller.low.decoder.axis_ids = {a.s.ll_id for a in self.controller.axes}

        return self._settings(
            call,
            self._per_axis(lambda a: a.s.ll_id, store, lambda a, v: within(1, 254, integer=True)(v), Fmt.I),
        )

    def z2b(self, call: Call) -> Reply:
        """Z2B: `L?` gives the hardware index, `L=code` renames the axis after SS Z and a reset (MS-115)."""

        def check(axis: Axis, value: float) -> float:
            code = within(65, 90, integer=True)(value)
            if any(other is not axis and other.letter == chr(int(code)) for other in self.controller.axes):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return code

        return self._settings(
            call, self._per_axis(lambda a: a.index, lambda a, v: setattr(a.s, "rename", int(v)), check, Fmt.I)
        )

    def place(self, name: str, call: Call) -> Reply:
        """SL, SU, HM: machine positions reported from the current origin; `+` here, `-` factory;
        remembered at once; on Z an SL at or above SU (or SU at or below SL) is ignored (MS-65, MS-68)."""
        t = call.now
        controller = self.controller

        def factory(axis: Axis) -> float:
            return getattr(controller.power.factory_auto(axis.hw_letter), name)

        def store(axis: Axis, machine_mm: float) -> None:
            if axis.letter == "Z" and name == "soft_lower" and machine_mm >= axis.auto.soft_upper:
                return
            if axis.letter == "Z" and name == "soft_upper" and machine_mm <= axis.auto.soft_lower:
                return
            setattr(axis.auto, name, machine_mm)

        params = self._per_axis(
            lambda a: a.user_of_machine_mm(getattr(a.auto, name)),
            lambda a, v: store(a, a.machine_mm_of_user(v)),
            None,
            Fmt.F3,
            plus=lambda a: store(a, a.machine_mm_of_user(a.user_mm(t))),
            minus=lambda a: store(a, factory(a)),
        )
        reply = self._settings(call, params)
        if any(i.kind is not Kind.QUERY for i in call.items):
            controller.power.save_auto()
        return reply

    def joystick(self, call: Call) -> Reply:
        """JOYSTICK: `+`/`-` enable/disable manual input, `=n` picks the input device (MS-73)."""
        controller = self.controller
        return self._settings(
            call,
            self._per_axis(
                lambda a: a.s.input_device,
                lambda a, v: setattr(a.s, "input_device", int(v)),
                lambda a, v: one_of(0, 2, 3, 22)(v),
                Fmt.I,
                plus=lambda a: controller.set_manual_enabled(a, True, call.now),
                minus=lambda a: controller.set_manual_enabled(a, False, call.now),
            ),
        )

    def jsspd(self, call: Call) -> Reply:
        """JSSPD: joystick fast/slow, wheel, knob speeds; named replies (MS-74)."""
        card = self.controller.card

        def speed(value: float) -> float:
            if not 0.1 <= abs(value) <= 100:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def show(attr: str) -> Callable[[], str]:
            def text() -> str:
                value = getattr(card, attr)
                return integer(value) if float(value).is_integer() else f6(value)

            return text

        params = {
            "X": Param(show("js_fast"), lambda v: setattr(card, "js_fast", v), speed, name="JS_FAST"),
            "Y": Param(show("js_slow"), lambda v: setattr(card, "js_slow", v), speed, name="JS_SLOW"),
            "Z": Param(
                lambda: card.js_wheel, lambda v: setattr(card, "js_wheel", v), speed, Fmt.F6, "JS_WHEEL"
            ),
            "F": Param(
                lambda: card.knob_slow,
                lambda v: setattr(card, "knob_slow", v),
                within(0.001, 100),
                Fmt.F6,
                "KNOB_SLOW",
            ),
            "T": Param(
                lambda: card.knob_mult,
                lambda v: setattr(card, "knob_mult", int(v)),
                within(1, 10, integer=True),
                Fmt.I,
                "KNOB_MULT",
            ),
        }
        if self.controller.knobs.knob_speeds_need_module and "XY KNOBS" not in self.controller.cfg.modules:
            # MS-KNOB-1 other reading: only builds with the side knobs define F and T (MS-30)
            del params["F"], params["T"]
        return self._settings(call, params, PSEUDO_ORDER)

    def rtime(self, call: Call) -> Reply:
        """RTIME: report period, pulse length, delay, averaging (MS-93)."""
        card = self.controller.card

        def param(attr: str, low: float, high: float) -> Param:
            return Param(
                lambda: getattr(card, attr), lambda v: setattr(card, attr, v), within(low, high), Fmt.F6
            )

        params = {
            "X": param("rt_report_ms", 20, 32700),
            "Y": param("rt_pulse_ms", 1, 65000),
            "Z": param("rt_delay_ms", 0, 65000),
            "F": param("rt_averages", 0, 8),
        }
        return self._settings(call, params, PSEUDO_ORDER)

    def ensync(self, call: Call) -> Reply:
        """ENSYNC: X or Y; the output goes low and toggles at each crossing (MS-95)."""
        controller = self.controller

        def store(axis: Axis, value: float) -> None:
            for other in controller.axes:
                other.ensync_mm = None
            controller.ensync_level = 0
            axis.set_ensync(call.now, value)

        params = {k: p for k, p in self._per_axis(lambda a: a.ensync_mm or 0.0, store).items() if k in "XY"}
        return self._settings(call, params)

    def customa(self, call: Call) -> Reply:
        """CUSTOMA: stored values; X is remembered at once (MS-97)."""
        controller = self.controller
        card = controller.card

        def store_x(value: float) -> None:
            controller.card_auto.cca_x = int(value)
            controller.power.save_auto()

        check = within(-32768, 32767, integer=True)
        params = {
            "X": Param(lambda: controller.card_auto.cca_x, store_x, check),
            "Y": Param(lambda: card.cca_y, lambda v: setattr(card, "cca_y", int(v)), check),
            "Z": Param(lambda: card.cca_z, lambda v: setattr(card, "cca_z", int(v)), check),
        }
        return self._settings(call, params, PSEUDO_ORDER)

    def stopbits(self, call: Call) -> Reply:
        """STOPBITS: 1 or 2, effective at once (MS-3)."""
        card = self.controller.card
        params = {
            "X": Param(lambda: card.stop_bits, lambda v: setattr(card, "stop_bits", int(v)), one_of(1, 2))
        }
        return self._settings(call, params, "X")

    def vb(self, call: Call) -> Reply:
        """VB: X unsolicited-output bits, Y IN1 (read-only), Z WHERE decimals (MS-96, MS-109)."""
        controller = self.controller
        card = controller.card
        params = {
            "X": Param(
                lambda: card.vb_flags,
                lambda v: setattr(card, "vb_flags", int(v)),
                within(0, 63, integer=True),
            ),
            "Y": Param(lambda: controller.ttl.in1),
            "Z": Param(
                lambda: card.vb_decimals,
                lambda v: setattr(card, "vb_decimals", int(v)),
                within(0, 6, integer=True),
            ),
        }
        params.update(controller.modules.extra_params(call.key))  # `VB T` with NO CHANGE SETTINGS (MS-109)
        reply = self._settings(call, params, PSEUDO_ORDER)
        if controller.knobs.vb_silent and reply == controller.ack():
            return SILENT
        return reply
