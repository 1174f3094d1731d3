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
        controller = self.controller
        card = controller.card
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            return self._list(call, ["0" if controller.ttl.in0 else "1"])

        def in_mode(value: float) -> float:
            if value != int(value) or not controller.in0_available(int(value)):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def out_mode(value: float) -> float:
            if value != int(value) or int(value) not in controller.out0_modes():
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
            controller.modules.emit(In0ModeChanged(t, card.ttl_in))
        if "ttl_out" in changed:
            controller.modules.emit(Out0ModeChanged(t, card.ttl_out))
        if changed & {"ttl_out", "ttl_polarity"}:
            controller.ttl.apply_mode(t)
        trailing = _number_after(call.items, "Y")
        if "ttl_out" in changed and trailing is not None:
            controller.modules.emit(TtlTrailingValue(t, card.ttl_out, trailing))
            controller.ttl.refresh(t)
        return reply

    def benable(self, call: Call) -> Reply:
        """BENABLE: enable byte (X as 0/1, Z as bits), F runs a function, R/T/M assign presses."""
        controller = self.controller
        card = controller.card
        buttons = controller.buttons

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
        controller = self.controller
        bca = controller.card_auto.bca

        def function(value: float) -> float:
            if not controller.buttons.valid_function(value):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def store(letter: str, value: float) -> None:
            bca[letter] = int(value)
            controller.power.save_auto()

        def get(letter: str) -> float:
            return bca.get(letter, 0)

        params = {k: Param(partial(get, k), partial(store, k), function) for k in PSEUDO_ORDER}
        return self._settings(call, params, PSEUDO_ORDER)

    def extra(self, call: Call) -> Reply:
        """EXTRA M: the button-flag byte, cleared when read; `M=n` runs the presses (MS-86)."""
        controller = self.controller
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
            return self._list(call, [str(controller.buttons.take_flags())])
        controller.buttons.set_flags(max(0, min(127, int(number(item)))), call.now)
        return controller.ack()

    def version(self, call: Call) -> Reply:
        """VERSION: `:A Version: <version> ` (MS-99)."""
        trailing = " " if self.controller.knobs.version_trailing_space else ""
        return Reply.text(f":A Version: {self.controller.cfg.version}{trailing}")

    def build(self, call: Call) -> Reply:
        """BUILD: name; X the module list; Y the user string; Z the volatile counter (MS-101…MS-104)."""
        controller = self.controller
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            return Reply.text(controller.cfg.build_name)
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in ("X", "Y", "Z")
        ]
        first_error(codes)
        if any(i.letter == "X" for i in items):
            return Reply.text(*info.build_lines(controller))
        text = controller.card.user_string
        counter = controller.user_counter
        reply: Reply = controller.ack()
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
        controller.card.user_string = text
        controller.user_counter = counter
        return reply

    def info(self, call: Call) -> Reply:
        """INFO: one block per axis; an absent axis makes it silent (MS-106, MS-107)."""
        controller = self.controller
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        axes = [controller.axis_named(i.letter) if i.letter else None for i in items]
        if any(a is None for a in axes):
            return (
                controller.error(ErrorCode.BAD_AXIS)
                if controller.knobs.info_absent_axis == "error"
                else SILENT
            )
        lines: list[str] = []
        for axis in sorted({a for a in axes if a is not None}, key=lambda a: a.index):
            if lines:
                lines.append("")
            lines.extend(info.info_block(controller, axis, call.now))
        return Reply.text(*lines)

    def dump(self, call: Call) -> Reply:
        """DUMP: trajectory buffer; X clears; Y error log newest first; F controller log (MS-108)."""
        controller = self.controller
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            return (
                Reply.text(*controller.trajectory_log, ":A")
                if controller.trajectory_log
                else controller.ack()
            )
        codes = [
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.letter not in ("X", "Y", "F")
        ]
        first_error(codes)
        item = items[-1]
        if item.letter == "X":
            controller.trajectory_log.clear()
            controller.error_log.clear()
            return controller.ack()
        if item.letter == "Y":
            return Reply.text(*(str(c) for c in reversed(controller.error_log)), ":A")
        if item.kind is Kind.SET:
            if number(item) != 999:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            controller.log_since = call.now
            controller.moves = 0
            for axis in controller.axes:
                axis.distance_mm = 0.0
            return controller.ack()
        xy = sum(a.distance_mm for a in controller.axes if a.letter in "XY")
        return Reply.text(
            f"On time: {int(call.now - controller.log_since)} s",
            f"XY distance: {f6(xy)} mm",
            f"Moves: {controller.moves}",
            ":A",
        )

    def saveset(self, call: Call) -> Reply | Pending:
        """SAVESET: Z save, X factory at next power-up, Y cancel; `:A` once saved (MS-110, MS-111)."""
        controller = self.controller
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
                controller.power.save_settings()
            else:
                controller.power.schedule_factory_reset(item.letter == "X")
        return controller.power.settled_ack()

    def savepos(self, call: Call) -> Reply:
        """SAVEPOS: X inhibits the power-off position save; bare SP saves and goes silent (MS-113)."""
        controller = self.controller
        card = controller.card
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            controller.halt_all(call.now)
            controller.power.save_positions(call.now)
            # this reply still goes out; nothing after it is read, queued lines included
            controller.interpreter.silence()
            return controller.ack()

        def inhibit(value: float) -> None:
            card.inhibit_position_save = int(value)
            controller.positions_changed()  # saved at once: it decides what a kill leaves (MS-111)

        params = {"X": Param(lambda: card.inhibit_position_save, inhibit, one_of(0, 1))}
        return self._settings(call, params, "X")

    def reset(self, call: Call) -> Reply:
        """RESET `~`: reply first, then the software reset (MS-112)."""
        self.controller.at(call.now, self.controller.power.software_reset)
        return self.controller.ack()

    def azero(self, call: Call) -> Reply | Pending:
        """AZERO: 0.5 s zero balancing, replying when done; `L?` reads 127 (MS-98, MS-33)."""
        controller = self.controller
        picked = self._axis_items(call)
        if all(i.kind is Kind.QUERY for _, i in picked):
            render = controller.render(call.key)
            return render.items((a.letter, str(AZ_READING)) for a, _ in picked)
        letters = {a.hw_letter for a, _ in picked}

        def finish(t: float) -> Reply:
            failed = letters & controller.az_fail
            controller.az_fail -= letters
            return Reply.text("NOT Zerod") if failed else controller.ack()

        return Pending(call.now + AZ_SECONDS, finish)

    def lcd(self, call: Call) -> Reply:
        """LCD "text": bottom line text, truncated to 20; without quotes the line clears (MS-116)."""
        match = _QUOTED.search(call.args)
        self.controller.lcd_text = match.group(1)[:20] if match else ""
        return self.controller.ack()

    def units(self, call: Call) -> Reply:
        """UNITS: toggle the LCD between mm and inches (MS-116)."""
        self.controller.lcd_inches = not self.controller.lcd_inches
        return self.controller.ack()


def _number_after(items: tuple[Item, ...], letter: str) -> float | None:
    """The bare number directly after the set item of `letter` (MS-24, MS-LED-3)."""
    for before, after in itertools.pairwise(items):
        if before.kind is Kind.SET and before.letter == letter and after.kind is Kind.NUMBER:
            return after.value
    return None
