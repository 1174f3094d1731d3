"""TTL, buttons and housekeeping (§6.7, §7): TTL, BENABLE, BCUSTOM, EXTRA, VERSION, BUILD, INFO,
DUMP, SAVESET, SAVEPOS, RESET, AZERO, LCD and UNITS."""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable
from functools import partial

from emulator.devices.ms2000 import info
from emulator.devices.ms2000.calls import (
    PSEUDO_ORDER,
    SILENT,
    Call,
    CommandError,
    Param,
    Pending,
    Reply,
    first_error,
    number,
    one_of,
    within,
)
from emulator.devices.ms2000.commands.base import CommandSet
from emulator.devices.ms2000.modules.events import In0ModeChanged, Out0ModeChanged, TtlTrailingValue
from protocols.ms2000 import ErrorCode, Item, Kind, f6

AZ_SECONDS = 0.5
AZ_READING = 127
USER_STRING_MAX = 20
_QUOTED = re.compile(r'"([^"]*)"')


class SystemCommands(CommandSet):
    def ttl(self, call: Call) -> Reply:
        """TTL X=in Y=out Z=aux F=polarity; bare TTL reads IN0 inverted (MS-89…MS-92, MS-LED-3)."""
        ctl = self.ctl
        card = ctl.card
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            return self._list(call, ["0" if ctl.ttl.in0 else "1"])

        def in_mode(value: float) -> float:
            if value != int(value) or not ctl.in0_available(int(value)):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def out_mode(value: float) -> float:
            if value != int(value) or int(value) not in ctl.out0_modes():
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        changed: set[str] = set()

        def setter(attr: str) -> Callable[[float], None]:
            def store(value: float) -> None:
                setattr(card, attr, int(value))
                changed.add(attr)

            return store

        params = {
            "X": Param(lambda: card.ttl_in, setter("ttl_in"), in_mode),
            "Y": Param(lambda: card.ttl_out, setter("ttl_out"), out_mode),
            "Z": Param(lambda: card.ttl_aux, setter("ttl_aux"), within(0, 255, integer=True)),
            "F": Param(lambda: card.ttl_polarity, setter("ttl_polarity"), one_of(1, -1)),
        }
        reply = self._settings(call, params, PSEUDO_ORDER)
        t = call.now
        if "ttl_in" in changed:
            ctl.modules.emit(In0ModeChanged(t, card.ttl_in))
        if "ttl_out" in changed:
            ctl.modules.emit(Out0ModeChanged(t, card.ttl_out))
        if changed & {"ttl_out", "ttl_polarity"}:
            ctl.ttl.apply_mode(t)
        trailing = _number_after(call.items, "Y")
        if "ttl_out" in changed and trailing is not None:
            ctl.modules.emit(TtlTrailingValue(t, card.ttl_out, trailing))
            ctl.ttl.refresh(t)
        return reply

    def benable(self, call: Call) -> Reply:
        """BENABLE: enable byte (X as 0/1, Z as bits), F runs a function, R/T/M assign presses."""
        ctl = self.ctl
        card = ctl.card
        buttons = ctl.buttons

        def function(value: float) -> float:
            if not buttons.valid_function(value):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def assign(attr: str) -> Param:
            return Param(lambda: getattr(card, attr), lambda v: setattr(card, attr, int(v)), function)

        params = {
            "X": Param(
                lambda: card.button_enable,
                lambda v: setattr(card, "button_enable", 15 if v else 0),
                one_of(0, 1),
            ),
            "Z": Param(
                lambda: card.button_enable,
                lambda v: setattr(card, "button_enable", int(v)),
                within(0, 31, integer=True),
            ),
            "F": Param(lambda: 0, lambda v: buttons.run_function(int(v), call.now), function),
            "R": assign("button_home_normal"),
            "T": assign("button_joystick_extra"),
            "M": assign("button_zero_normal"),
        }
        return self._settings(call, params, PSEUDO_ORDER)

    def bcustom(self, call: Call) -> Reply:
        """BCUSTOM: function numbers of the other press classes, remembered at once (MS-86)."""
        ctl = self.ctl
        bca = ctl.card_auto.bca

        def function(value: float) -> float:
            if not ctl.buttons.valid_function(value):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def store(letter: str, value: float) -> None:
            bca[letter] = int(value)
            ctl.power.save_auto()

        def get(letter: str) -> float:
            return bca.get(letter, 0)

        params = {k: Param(partial(get, k), partial(store, k), function) for k in PSEUDO_ORDER}
        return self._settings(call, params, PSEUDO_ORDER)

    def extra(self, call: Call) -> Reply:
        """EXTRA M: the button-flag byte, cleared when read; `M=n` runs the presses (MS-86)."""
        ctl = self.ctl
        picked = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not picked:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in picked
            if i.letter != "M"
        ]
        first_error(codes)
        item = picked[-1]
        if item.kind is Kind.QUERY:
            return self._list(call, [str(ctl.buttons.take_flags())])
        ctl.buttons.set_flags(max(0, min(127, int(number(item)))), call.now)
        return ctl.ack()

    def version(self, call: Call) -> Reply:
        """VERSION: `:A Version: <version> ` (MS-99)."""
        trailing = " " if self.ctl.knobs.version_trailing_space else ""
        return Reply.text(f":A Version: {self.ctl.cfg.version}{trailing}")

    def build(self, call: Call) -> Reply:
        """BUILD: name; X the module list; Y the user string; Z the volatile counter (MS-101…MS-104)."""
        ctl = self.ctl
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            return Reply.text(ctl.cfg.build_name)
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in ("X", "Y", "Z")
        ]
        first_error(codes)
        if any(i.letter == "X" for i in items):
            return Reply.text(*info.build_lines(ctl))
        text = ctl.card.user_string
        counter = ctl.user_counter
        reply: Reply = ctl.ack()
        for item in items:
            if item.letter == "Y":
                if item.kind is Kind.QUERY:
                    reply = Reply((text.encode("latin-1"),))
                elif item.kind is Kind.MINUS:
                    text = ""
                else:
                    code = number(item)
                    if not 32 <= code <= 126 or code != int(code) or len(text) >= USER_STRING_MAX:
                        raise CommandError(ErrorCode.OUT_OF_RANGE)
                    text += chr(int(code))
            elif item.kind is Kind.QUERY:
                reply = self._list(call, [str(counter)])
            elif item.kind is Kind.PLUS:
                counter = (counter + 1) % 65536
            elif item.kind is Kind.MINUS:
                counter = (counter - 1) % 65536
            else:
                value = number(item)
                if not 0 <= value <= 65535 or value != int(value):
                    raise CommandError(ErrorCode.OUT_OF_RANGE)
                counter = int(value)
        ctl.card.user_string = text
        ctl.user_counter = counter
        return reply

    def info(self, call: Call) -> Reply:
        """INFO: one block per axis; an absent axis makes it silent (MS-106, MS-107)."""
        ctl = self.ctl
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        axes = [ctl.axis_named(i.letter) if i.letter else None for i in items]
        if any(a is None for a in axes):
            return ctl.error(ErrorCode.BAD_AXIS) if ctl.knobs.info_absent_axis == "error" else SILENT
        lines: list[str] = []
        for axis in sorted({a for a in axes if a is not None}, key=lambda a: a.index):
            if lines:
                lines.append("")
            lines.extend(info.info_block(ctl, axis, call.now))
        return Reply.text(*lines)

    def dump(self, call: Call) -> Reply:
        """DUMP: trajectory buffer; X clears; Y error log newest first; F controller log (MS-108)."""
        ctl = self.ctl
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            return Reply.text(*ctl.trajectory_log, ":A") if ctl.trajectory_log else ctl.ack()
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in ("X", "Y", "F")
        ]
        first_error(codes)
        item = items[-1]
        if item.letter == "X":
            ctl.trajectory_log.clear()
            ctl.error_log.clear()
            return ctl.ack()
        if item.letter == "Y":
            return Reply.text(*(str(c) for c in reversed(ctl.error_log)), ":A")
        if item.kind is Kind.SET:
            if number(item) != 999:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            ctl.log_since = call.now
            ctl.moves = 0
            for axis in ctl.axes:
                axis.distance_mm = 0.0
            return ctl.ack()
        xy = sum(a.distance_mm for a in ctl.axes if a.letter in "XY")
        return Reply.text(
            f"On time: {int(call.now - ctl.log_since)} s",
            f"XY distance: {f6(xy)} mm",
            f"Moves: {ctl.moves}",
            ":A",
        )

    def saveset(self, call: Call) -> Reply | Pending:
        """SAVESET: Z save, X factory at next power-up, Y cancel; `:A` once saved (MS-110, MS-111)."""
        ctl = self.ctl
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in ("X", "Y", "Z")
        ]
        first_error(codes)
        for item in items:
            if item.letter == "Z":
                ctl.power.save_settings()
            else:
                ctl.power.schedule_factory_reset(item.letter == "X")
        return ctl.power.settled_ack()

    def savepos(self, call: Call) -> Reply:
        """SAVEPOS: X inhibits the power-off position save; bare SP saves and goes silent (MS-113)."""
        ctl = self.ctl
        card = ctl.card
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            ctl.halt_all(call.now)
            ctl.power.save_positions(call.now)
            # this reply still goes out; nothing after it is read, queued lines included
            ctl.interpreter.silence()
            return ctl.ack()

        def inhibit(value: float) -> None:
            card.inhibit_position_save = int(value)
            ctl.positions_changed()  # saved at once: it decides what a kill leaves (MS-111)

        params = {"X": Param(lambda: card.inhibit_position_save, inhibit, one_of(0, 1))}
        return self._settings(call, params, "X")

    def reset(self, call: Call) -> Reply:
        """RESET `~`: reply first, then the software reset (MS-112)."""
        self.ctl.at(call.now, self.ctl.power.software_reset)
        return self.ctl.ack()

    def azero(self, call: Call) -> Reply | Pending:
        """AZERO: 0.5 s zero balancing, replying when done; `L?` reads 127 (MS-98, MS-33)."""
        ctl = self.ctl
        picked = self._axis_items(call)
        if all(i.kind is Kind.QUERY for _, i in picked):
            render = ctl.render(call.key)
            return render.items((a.letter, str(AZ_READING)) for a, _ in picked)
        letters = {a.hw_letter for a, _ in picked}

        def finish(t: float) -> Reply:
            failed = letters & ctl.az_fail
            ctl.az_fail -= letters
            return Reply.text("NOT Zerod") if failed else ctl.ack()

        return Pending(call.now + AZ_SECONDS, finish)

    def lcd(self, call: Call) -> Reply:
        """LCD "text": bottom line text, truncated to 20; without quotes the line clears (MS-116)."""
        match = _QUOTED.search(call.args)
        self.ctl.lcd_text = match.group(1)[:20] if match else ""
        return self.ctl.ack()

    def units(self, call: Call) -> Reply:
        """UNITS: toggle the LCD between mm and inches (MS-116)."""
        self.ctl.lcd_inches = not self.ctl.lcd_inches
        return self.ctl.ack()


def _number_after(items: tuple[Item, ...], letter: str) -> float | None:
    """The bare number directly after the set item of `letter` (MS-24, MS-LED-3)."""
    for before, after in itertools.pairwise(items):
        if before.kind is Kind.SET and before.letter == letter and after.kind is Kind.NUMBER:
            return after.value
    return None
