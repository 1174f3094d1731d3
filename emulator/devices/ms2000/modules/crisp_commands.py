"""CRISP's commands (§9.5): LOCK (`LK`), LOCKRG (`LR`), UNLOCK (`UL`), AFLIM (`AL`), `EXTRA X/Y/Z`
and, in OUT0 mode 11, STATUS (`/`).

- `LK` without items advances like the panel button; `LK X?` the state character (never a trailing
  space, MS-38); `LK Y?`, `Z?`, `T?`, `M?` the error, offset, sum and AGC value, always with one
  trailing space (MS-CRISP-4); `LK F=code` or the historical `LK X=code` (MS-CRISP-3), bare `LK X`
  a no-op. Several queries in one command answer in the order X Y Z F T M (MS-29); `LK F?` reads
  like `LK X?`; setting the readings `Y` or `T` is out of range [choice].
- `EXTRA X?` the LCD line, bare; `EXTRA Y?` the SNR with one decimal; `EXTRA Z=n` (0–100) the
  integral gain, `EXTRA Z?` F6 [choice]; one reading per reply, the first in X Y Z order [choice];
  anything with `M` (or no items) is the base command (MS-86).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from emulator.devices.ms2000.calls import (
    PSEUDO_ORDER,
    Call,
    CommandError,
    Param,
    Pending,
    Reply,
    first_error,
    number,
    run_settings,
    within,
)
from emulator.devices.ms2000.modules import Handler
from emulator.devices.ms2000.modules import crisp_states as st
from emulator.devices.ms2000.modules.crisp_settings import (
    OFFSET_LIMIT,
    aflim_params,
    lockrg_params,
    unlock_params,
)
from protocols.ms2000 import ErrorCode, Kind, f6

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.crisp import Crisp

LK_LETTERS = "XYZFTM"


class CrispCommands:
    def __init__(self, crisp: Crisp) -> None:
        self.crisp = crisp

    def _settings(self, call: Call, params: dict[str, Param]) -> Reply:
        controller = self.crisp.controller
        return run_settings(call, params, PSEUDO_ORDER, controller.render(call.key), controller.ack())

    def table(self) -> dict[str, Handler]:
        return {
            "LK": self.lock,
            "LR": self.lockrg,
            "UL": self.unlock,
            "AL": self.aflim,
            "EX": self.extra,
            "/": self.status,
        }

    def lock(self, call: Call) -> Reply:
        """LOCK (MS-CRISP-1, MS-CRISP-3, MS-CRISP-4)."""
        now = call.now
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            self.crisp.advance(now)
            return self.crisp.controller.ack()
        codes: list[int] = []
        sets: dict[str, int] = {}
        queries: list[str] = []
        for item in items:
            letter = item.letter or ""
            if item.kind is Kind.MALFORMED:
                codes.append(ErrorCode.UNDEFINED)
            elif letter not in LK_LETTERS:
                codes.append(ErrorCode.BAD_AXIS)
            elif item.kind is Kind.QUERY:
                queries.append(letter)
            elif letter == "X" and item.kind is Kind.BARE:
                continue  # historical no-op
            elif letter in "YT":
                codes.append(ErrorCode.OUT_OF_RANGE)  # readings, not settings [choice]
            else:
                try:
                    sets[letter] = self._checked(letter, number(item))
                except CommandError as exc:
                    codes.append(exc.code)
        first_error(codes)
        if "Z" in sets:
            self.crisp.settings.offset = sets["Z"]
        if "M" in sets:
            self.crisp.settings.agc = sets["M"]
        code = sets.get("F", sets.get("X"))
        if code is not None:
            self.crisp.apply_code(code, now)
        self.crisp.sync(now)
        if not queries:
            return self.crisp.controller.ack()
        values = {
            "X": self.crisp.state,
            "Y": str(self.crisp.error(now)),
            "Z": str(self.crisp.settings.offset),
            "F": self.crisp.state,
            "T": str(self.crisp.signal_sum()),
            "M": str(self.crisp.settings.agc),
        }
        ordered = [letter for letter in PSEUDO_ORDER if letter in queries]
        numeric = any(letter not in "XF" for letter in ordered)
        rendered = replace(
            self.crisp.controller.render(call.key), trailing_space=numeric
        )  # MS-38, MS-CRISP-4
        return rendered.items([(letter, values[letter]) for letter in ordered])

    @staticmethod
    def _checked(letter: str, value: float) -> int:
        if letter in "XF":
            if not st.valid_code(value):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return int(value)
        if letter == "Z":
            return int(within(-OFFSET_LIMIT, OFFSET_LIMIT, integer=True)(value))
        return int(within(0, 255, integer=True)(value))

    def lockrg(self, call: Call) -> Reply:
        """LOCKRG X=cal_gain Y=NA Z=lock_range F=cal_range T=loop_gain (MS-CRISP-5)."""
        params = lockrg_params(self.crisp.settings)
        return self._settings(call, params)

    def unlock(self, call: Call) -> Reply:
        """UNLOCK: bare, release the lock keeping the offset; else its settings (MS-CRISP-5)."""
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            if self.crisp.state in st.ENGAGED:
                self.crisp.enter(st.READY, call.now)
            return self.crisp.controller.ack()
        params = unlock_params(self.crisp.settings, len(self.crisp.controller.axes))
        return self._settings(call, params)

    def aflim(self, call: Call) -> Reply:
        """AFLIM X=agc Y=led_pot Z=in_focus_mm (MS-CRISP-5); bare `:N-3` (MS-31)."""
        params = aflim_params(self.crisp.settings)
        return self._settings(call, params)

    def extra(self, call: Call) -> Reply | Pending:
        """EXTRA X? (the LCD line), Y? (SNR), Z (integral gain); `M` is the base command's (MS-86)."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items or any(i.letter == "M" for i in items):
            return self.crisp.controller.base_handler(call.key)(call)
        codes: list[int] = []
        gain: float | None = None
        for item in items:
            if item.kind is Kind.MALFORMED:
                codes.append(ErrorCode.UNDEFINED)
            elif item.letter not in ("X", "Y", "Z"):
                codes.append(ErrorCode.BAD_AXIS)
            elif item.kind is not Kind.QUERY and item.letter != "Z":
                codes.append(ErrorCode.OUT_OF_RANGE)  # readings [choice]
            elif item.kind is not Kind.QUERY:
                try:
                    gain = within(0, 100)(number(item))
                except CommandError as exc:
                    codes.append(exc.code)
        first_error(codes)
        if gain is not None:
            self.crisp.settings.integral_gain = gain
        queried = [
            letter for letter in "XYZ" if any(i.letter == letter and i.kind is Kind.QUERY for i in items)
        ]
        if not queried:
            return self.crisp.controller.ack()
        first = queried[0]  # one reading per reply [choice]
        if first == "X":
            return Reply.text(self.crisp.extra_line(call.now))
        if first == "Y":
            return Reply.text(f":A {self.crisp.snr():.1f}")
        return self.crisp.controller.render(call.key).items([("Z", f6(self.crisp.settings.integral_gain))])

    def status(self, call: Call) -> Reply | Pending:
        """STATUS: in OUT0 mode 11 also `B` while a move's pulse waits for `F` (MS-CRISP-7)."""
        self.crisp.sync(call.now)
        if self.crisp.move_pulse_waiting():
            return Reply.text("B")
        return self.crisp.controller.base_handler(call.key)(call)
