"""The controller's command line: host bytes -> lines -> handlers -> framed replies.

It owns line assembly (`max_line`, MS-9), the 0xFF control sequences and the switch to low-level
mode (MS-119), the lines waiting behind a command that replies late (MS-13, MS-33), HALT's way past
them (MS-76) and the silence after a bare `SP` (MS-113).

While explaining it notes each unit it reads: a command line or control sequence (`frame`, the line's
bytes kept in `_heard`), junk or an unknown control sequence (`stray`), input it drops (`lost`); and
names the line each reply answers.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Protocol

from emulator.device import FRAME, LOST, STRAY, Notes
from emulator.devices.ms2000.calls import Call, CommandError, Handler, Pending, Reply
from protocols import ms2000 as proto
from protocols.ms2000 import ErrorCode

if TYPE_CHECKING:
    from emulator.devices.ms2000.lowlevel import LowLevel
    from emulator.devices.ms2000.scheduler import Scheduler, Timer
    from emulator.devices.ms2000.schema import Ms2000Config
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.settings import CardSettings

_CONTROL_BYTE = bytes((proto.CONTROL,))
#: a line's command (None: unknown), its items and the raw text of its arguments
Parsed = tuple[proto.CommandSpec | None, tuple[proto.Item, ...], str]
#: what a blank line parses to (told apart from an unknown command by identity)
BLANK: Parsed = (None, (), "")
#: parsed lines kept at most (then forgotten at once): the few a host polls, not everything it sent
PARSED_LINES = 256

#: the 0xFF control sequences (MS-119), for the traffic log
CONTROL_SEQUENCES = {
    0x42: "enter low-level mode",
    0x41: "return to high-level mode",
    0x52: "reset",
    0x48: "WHERE in hundredths of a micron",
    0x54: "WHERE in tenths of a micron",
}


class Resets(Protocol):
    def software_reset(self, t: float) -> None:
        """`~` or `RESET` (MS-112)."""


class InterpreterOwner(Protocol):
    """All the command line uses of its controller."""

    @property
    def now(self) -> float:
        """Device time of the last step (a line dropped outside a step is noted then)."""

    @property
    def cfg(self) -> Ms2000Config: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def card(self) -> CardSettings:
        """`VB` flags and decimals; `\\` and `/` of low-level mode set the decimals (§8)."""

    @property
    def notes(self) -> Notes: ...

    @property
    def scheduler(self) -> Scheduler:
        """A reply's due time; the timers due as a line completes."""

    @property
    def low(self) -> LowLevel: ...

    @property
    def power(self) -> Resets: ...

    def error(self, code: int) -> Reply: ...

    def send_raw(self, data: bytes, t: float, to: str | None = None) -> None: ...


class Interpreter:
    def __init__(self, controller: InterpreterOwner, handlers: dict[str, Handler]) -> None:
        self.controller = controller
        self.handlers = handlers
        self.low_level = False
        self.silenced = False
        self._line = bytearray()
        #: every byte of the line being read, beyond `max_line` too (while explaining)
        self._heard = bytearray()
        self._overflow = False
        self._ff = False
        #: bytes read while the host's settings mismatched (MS-4): dropped once they match again
        self._junk = False
        self._queue: deque[bytes | None] = deque()
        #: lines already parsed: hosts poll the same few lines over and over (`W X Y`, `/`), and a
        #: line's parse depends only on its bytes and the profile's knobs, which never change
        self._parsed: dict[bytes, Parsed] = {}
        #: the command waiting to reply, whether it ends lines with CR only, its timer and its line
        self._pending: tuple[Pending, bool, Timer | None, bytes | None] | None = None

    @property
    def mode(self) -> str:
        return "silent" if self.silenced else "low" if self.low_level else "high"

    def feed(self, data: bytes, t: float, garbled: bool) -> None:
        if garbled:
            self._junk = True
        elif self._junk:
            # MS-4 [choice]: what a mismatched host left half-assembled is dropped once its settings
            # match again, so its first line at the right settings is read cleanly (TV-120)
            self._junk = False
            self._drop_line(t, STRAY, "junk from a mismatched host, dropped (MS-4)")
            self.controller.low.drop(t, STRAY, "junk from a mismatched host, dropped (MS-4)")
        index = 0
        while index < len(data):
            if self.silenced:
                if self.controller.notes.on:
                    self.controller.notes.rx(t, LOST, data[index:], "silent after SP (MS-113)")
                return
            if self._ff or self.low_level:
                self._byte(data[index], t)
                index += 1
            else:
                index = self._text(data, index, t)

    def _text(self, data: bytes, start: int, t: float) -> int:
        """ASCII mode: take `data[start:]` up to and including the first CR or 0xFF, a run at a time
        rather than byte by byte (a whole command usually arrives in one read); returns where it
        stopped. The same as `_byte` for each of those bytes."""
        end = len(data)
        stop = data.find(b"\r", start)
        if stop < 0:
            stop = end
        control = data.find(_CONTROL_BYTE, start, stop)
        if control >= 0:
            stop = control
        if stop > start:
            run = data[start:stop]
            if self.controller.notes.on:
                self._heard += run
            room = self.controller.knobs.max_line - len(self._line)
            if len(run) > room:
                self._overflow = True
                run = run[: max(room, 0)]
            self._line += run
        if stop == end:
            return end
        self._byte(data[stop], t)
        return stop + 1

    def _drop_line(self, t: float, kind: str, why: str) -> None:
        """The partial line is discarded (noted as `kind` for `why`)."""
        if self._heard:
            self.controller.notes.rx(t, kind, bytes(self._heard), why)
            self._heard.clear()
        self._line.clear()
        self._overflow = False

    def _byte(self, byte: int, t: float) -> None:
        if self._ff:
            self._ff = False
            self._control_sequence(byte, t)
        elif byte == proto.CONTROL:
            self._ff = True
        elif self.low_level:
            self.controller.low.feed(byte, t)
        elif byte == 0x0D:
            line = None if self._overflow else bytes(self._line)
            self._line.clear()
            self._overflow = False
            self._on_line(line, t)
            self.controller.scheduler.run_due(t)
        else:
            if self.controller.notes.on:
                self._heard.append(byte)
            if len(self._line) >= self.controller.knobs.max_line:
                self._overflow = True
            else:
                self._line.append(byte)

    def _control_sequence(self, byte: int, t: float) -> None:
        controller = self.controller
        if controller.notes.on:
            name = CONTROL_SEQUENCES.get(byte)
            if byte == 0x42 and "LL COMMANDS" not in controller.cfg.modules:
                name = None  # MS-119: discarded without the module
            summary = f"FF {byte:02X}: {name or 'unknown control sequence, discarded'} (MS-119)"
            controller.notes.rx(t, FRAME if name else STRAY, bytes((proto.CONTROL, byte)), summary)
        if byte == 0x42:  # 'B'
            if "LL COMMANDS" in controller.cfg.modules:
                self.low_level = True
                self._drop_line(t, LOST, "partial line discarded entering low-level mode (MS-119)")
                controller.low.reset()
        elif byte == 0x41:  # 'A'
            self.low_level = False
            controller.low.drop(t, LOST, "partial frame dropped leaving low-level mode (MS-119)")
        elif byte == 0x52:  # 'R'
            controller.power.software_reset(t)
        elif byte == 0x48:  # 'H'
            controller.card.vb_decimals = 1
        elif byte == 0x54:  # 'T'
            controller.card.vb_decimals = 0

    def _on_line(self, line: bytes | None, t: float) -> None:
        pending = self._pending
        halts = pending is not None and line is not None and pending[0].haltable and self._is_halt(line)
        if self.controller.notes.on:
            self._heard.append(0x0D)
            waits = " (waits for the pending command, MS-13)" if pending is not None and not halts else ""
            self.controller.notes.rx(t, FRAME, bytes(self._heard), self.describe(line) + waits)
            self._heard.clear()
        if pending is not None:
            if halts:
                self.cancel_pending(t, reply=True)
                self._execute(line, t)
                self.drain(t)
            else:
                self._queue.append(line)
            return
        self._execute(line, t)

    @staticmethod
    def describe(line: bytes | None) -> str:
        """A command line for the traffic log (None: one over `max_line`, MS-9)."""
        return "over-long line (MS-9)" if line is None else proto.summarize_line(line)

    @staticmethod
    def _is_halt(line: bytes) -> bool:
        spec = proto.split_command(line.decode("latin-1")).spec
        return spec is not None and spec.key == "\\"

    def _execute(self, line: bytes | None, t: float) -> None:
        cr_only = bool(self.controller.card.vb_flags & 8)
        result = self._dispatch(line, t)
        if isinstance(result, Pending):
            due = result.due
            timer = None if due is None else self.controller.scheduler.at(due, self._finish_pending)
            self._pending = (result, cr_only, timer, line)
        else:
            self._send(result, t, cr_only, line)

    def _dispatch(self, line: bytes | None, t: float) -> Reply | Pending:
        controller = self.controller
        if line is None:
            return controller.error(ErrorCode.UNDEFINED)
        parsed = self._parsed.get(line)
        if parsed is None:
            parsed = self._parse(line)
            if len(self._parsed) >= PARSED_LINES:
                self._parsed.clear()
            self._parsed[line] = parsed
        if parsed is BLANK:
            ignore = controller.knobs.empty_line_reply == "ignore"
            return Reply(()) if ignore else controller.error(ErrorCode.UNKNOWN_COMMAND)
        spec, items, args = parsed
        handler = self.handlers.get(spec.key) if spec is not None else None
        if spec is None or handler is None:
            return controller.error(ErrorCode.UNKNOWN_COMMAND)
        try:
            return handler(Call(spec, items, args, t))
        except CommandError as exc:
            return controller.error(exc.code)

    def _parse(self, line: bytes) -> Parsed:
        text = line.decode("latin-1")
        if proto.is_blank(text):
            return BLANK
        parts = proto.split_command(text)
        if parts.spec is None:
            return None, (), parts.args
        numeric_prefix = self.controller.knobs.number_values == "prefix"
        return parts.spec, tuple(proto.parse_items(parts.args, numeric_prefix)), parts.args

    def _finish_pending(self, t: float) -> None:
        if self._pending is None:
            return
        pending, cr_only, _, line = self._pending
        self._pending = None
        self._send(pending.finish(t), t, cr_only, line)
        self.drain(t)

    def release(self, t: float) -> None:
        """What a pending command without a due time waits for has happened (the store settled)."""
        if self._pending is not None and self._pending[0].due is None:
            self._finish_pending(t)

    def cancel_pending(self, t: float, reply: bool) -> None:
        if self._pending is None:
            return
        pending, cr_only, timer, line = self._pending
        self._pending = None
        if timer is not None:
            timer.cancel()
        pending.cancel(t)
        if reply:
            self._send(self.controller.error(ErrorCode.HALTED), t, cr_only, line)

    def drain(self, t: float) -> None:
        while self._queue and self._pending is None and not self.silenced:
            self._execute(self._queue.popleft(), t)

    def _send(self, reply: Reply, t: float, cr_only: bool, line: bytes | None) -> None:
        if reply.lines:
            to = self.describe(line) if self.controller.notes.on else ""
            self.controller.send_raw(proto.frame(reply.lines, cr_only), t, to)

    # The calls below come from the controller's power and reset code, which runs at the latest
    # device time (`controller.now`): drops are noted then.

    def silence(self) -> None:
        """`SP` alone: ignore all input until a power cycle (MS-113)."""
        self.silenced = True
        self._drop_queue("silent after SP (MS-113)")
        self._drop_line(self.controller.now, LOST, "silent after SP (MS-113)")

    def restart(self) -> None:
        """Reset and power-up: back to ASCII mode with an empty line (MS-112)."""
        self.low_level = False
        self._drop_line(self.controller.now, LOST, "partial line dropped by a reset (MS-112)")

    def power_off(self) -> None:
        """Waiting lines, a half-received control sequence and the silence are gone (MS-113)."""
        self._drop_queue("waiting line dropped by a power cycle (MS-113)")
        self.silenced = False
        self._ff = False

    def _drop_queue(self, why: str) -> None:
        if self.controller.notes.on:
            for line in self._queue:
                data = b"" if line is None else line + b"\r"
                self.controller.notes.rx(self.controller.now, LOST, data, f"{self.describe(line)}: {why}")
        self._queue.clear()
