"""What the MP-285 makes of each character it accepts (docs/mp285.md §2, §3, §7).

Frames are delimited by the protocol's `FrameParser` and each completed item is handed to the
device. While an `m`, `k` or `e` is outstanding, bytes are treated per §7: ^C halts the move and is
acknowledged at once (MP-48), other bytes may interrupt it (MP-50, MP-51, MP-53), `c`/`s` frames are
answered at once and anything else is held, with all that follows, until the final reply (MP-52).
A frame left incomplete arms the lock-up timer (MP-80).

While explaining, the receiver notes each unit it parses with the bytes it took (`_heard`): an item
of the parser (`frame`, or `stray` for a lone terminator, a bad frame, an overrun) or input it drops
(`lost`). Held bytes are noted when they are replayed, as that is when they are parsed.
"""

from __future__ import annotations

from collections.abc import Callable

from emulator.device import FRAME, LOST, STRAY, Notes
from emulator.devices.mp285.commands import QUERY_BYTES
from emulator.devices.mp285.motion import Halt, Run
from emulator.devices.mp285.schema import Mp285Knobs
from protocols import mp285 as proto
from protocols.mp285 import CR, CTRL_C, LF, CtrlC, Frame, FrameParser, Item, ParseState

#: stands in held input for the `error8_4` drop of the frame being parsed, so that the drop is
#: replayed in its turn (MP-53, MP-52)
ABANDON_FRAME = (-1, False)


class Receiver:
    """The frame layer: parser, held input and the lock-up timer, with what the device lends it:
    `notes` for the traffic log, `execute(item, t)` runs a parsed item, `acknowledge(t)` answers a
    ^C during a move, `current_run()` is the outstanding run (None unless MOVING)."""

    def __init__(
        self,
        knobs: Mp285Knobs,
        notes: Notes,
        execute: Callable[[Item, float], None],
        acknowledge: Callable[[float], None],
        current_run: Callable[[], Run | None],
    ) -> None:
        self.parser = FrameParser(knobs.input_buffer_size)
        #: when an incomplete frame locks the controller up (MP-80), None when not armed
        self.lockup_at: float | None = None
        self._notes = notes
        #: bytes the parser took since its last item (while explaining)
        self._heard = bytearray()
        self._execute = execute
        self._acknowledge = acknowledge
        self._current_run = current_run
        self._lockup_s: float | None = knobs.lockup_incomplete_frame_s
        self._settle_s: float = knobs.settle_s
        self._drop_interrupting = knobs.move_interrupt_reply == "error8_4"
        self._terminators_interrupt: bool = knobs.terminators_interrupt_move
        self._queries_interrupt: bool = knobs.query_interrupts_move
        self._hold: list[tuple[int, bool]] | None = None
        self._epoch = 0  # bumped whenever queued input is thrown away (reset, power cycle, crash)
        self._dropped_by = ""  # why, for the traffic log

    def dispatch(self, byte: int, framing_error: bool, t: float, run: Run | None) -> None:
        """One accepted character at `t`; `run`: the outstanding run, None unless MOVING."""
        parser = self.parser
        if run is not None:
            self._byte_during_move(byte, framing_error, t, run)
        else:
            item = parser.feed_byte(byte, framing_error)
            if self._notes.on:
                self._took(byte, item, t)
            if item is not None:
                self._execute(item, t)
        limit = self._lockup_s
        in_frame = parser.state is not ParseState.COMMAND
        self.lockup_at = t + limit if limit is not None and in_frame else None  # MP-80

    def lost(self, t: float, byte: int, why: str) -> None:
        """While explaining: a byte the controller's state kept from the parser and dropped."""
        self._notes.rx(t, LOST, bytes((byte,)), why)

    def stray(self, t: float, byte: int, summary: str) -> None:
        """While explaining: a byte the controller's state handled outside any frame."""
        self._notes.rx(t, STRAY, bytes((byte,)), summary)

    def _took(self, byte: int, item: Item | None, t: float) -> None:
        """While explaining: the parser took `byte`; an item it completes is noted before it runs."""
        self._heard.append(byte)
        if item is not None:
            kind = FRAME if isinstance(item, Frame | CtrlC) else STRAY
            self._note(t, kind, proto.describe_item(item))

    def _note(self, t: float, kind: str, summary: str, extra: bytes = b"") -> None:
        data = bytes(self._heard) + extra
        self._heard.clear()
        if data:
            self._notes.rx(t, kind, data, summary)

    def drop(self, t: float, why: str, kept: bytes = b"") -> None:
        """Partial frames and held input are thrown away (MP-57, MP-76, MP-77); `why` and the byte
        `kept` in the MP-7 register go to the traffic log."""
        self._dropped_by = why
        if self._notes.on:
            self._note(t, LOST, f"dropped by {why}", _bytes(self._hold or ()) + kept)
        self._epoch += 1
        self.parser.reset()
        self._hold = None
        self.lockup_at = None

    def forget_frame(self, t: float, kept: bytes) -> None:
        """The frame being parsed and the byte `kept` in the register are lost (MP-7 overrun)."""
        if self._notes.on:
            self._note(t, LOST, "dropped by a receive register overrun (MP-7)", kept)
        self.parser.reset()
        self.lockup_at = None

    def release(self, t: float) -> None:
        """Replay held bytes as if they arrived now, in order (MP-52); a reset among them clears the
        rest (MP-57)."""
        held, self._hold = self._hold, None
        if not held:
            return
        self.parser.reset()
        epoch = self._epoch
        for index, (byte, framing_error) in enumerate(held):
            if self._epoch != epoch:
                if self._notes.on:
                    self._note(t, LOST, f"dropped by {self._dropped_by}", _bytes(held[index:]))
                break
            if (byte, framing_error) == ABANDON_FRAME:
                self._abandon_frame()
            else:
                self.dispatch(byte, framing_error, t, self._current_run())

    def _byte_during_move(self, byte: int, framing_error: bool, t: float, run: Run) -> None:
        """§7: a byte while an `m`, `k` or `e` is outstanding."""
        clean = not framing_error
        at_command = self.parser.state is ParseState.COMMAND
        if at_command and clean and byte == CTRL_C:
            self._ctrl_c_during_move(run, t)  # MP-48, even behind a held frame (MP-52)
            return
        if run.moving(t) and self._interrupts(byte, clean, at_command):
            run.halt(t, self._settle_s, Halt.BYTE)  # MP-51
            if self._drop_interrupting:  # MP-53 error8_4: the interrupting frame is dropped
                if not (at_command and clean and byte in (CR, LF)):
                    self._abandon_frame()
                    self._frame_during_move(byte, framing_error, t)
                elif self._notes.on:
                    self._notes.rx(t, STRAY, bytes((byte,)), "terminator interrupting a move (MP-50)")
                return
        self._frame_during_move(byte, framing_error, t)

    def _ctrl_c_during_move(self, run: Run, t: float) -> None:
        if self._notes.on:
            self._notes.rx(t, FRAME, bytes((CTRL_C,)), "^C during a move (MP-48)")
        self._acknowledge(t)
        if run.moving(t):
            run.halt(t, self._settle_s, Halt.CTRL_C)
        elif run.cause is None:
            run.cause = Halt.CTRL_C  # STOPPING ends as planned, but a program is abandoned (MP-54)

    def _interrupts(self, byte: int, clean: bool, at_command: bool) -> bool:
        """Does this byte halt a move in MOVING (MP-50, MP-51)?"""
        if at_command:
            if clean and byte in (CR, LF):
                return self._terminators_interrupt
            return not (clean and byte in QUERY_BYTES and not self._queries_interrupt)
        # inside a `c`/`s` frame that was let through: only a bad terminator interrupts
        return self.parser.expects_terminator and not (clean and byte == CR)

    def _frame_during_move(self, byte: int, framing_error: bool, t: float) -> None:
        """MP-52: `c`/`s` frames are answered at once; anything else is held, with all that follows,
        until the final reply has been sent."""
        parser = self.parser
        if self._hold is not None:
            parser.feed_byte(byte, framing_error)  # keep delimiting, to spot ^C in command position
            self._hold.append((byte, framing_error))
            return
        if parser.state is ParseState.DISCARDING:  # the silently dropped frame of MP-53 error8_4
            item = parser.feed_byte(byte, framing_error)
            if self._notes.on:
                self._took(byte, item, t)
            if item is not None:
                self._execute(item, t)
            return
        before = parser.frame_bytes
        item = parser.feed_byte(byte, framing_error)
        if isinstance(item, Frame) and item.raw[0] in QUERY_BYTES:
            if self._notes.on:
                self._took(byte, item, t)
            self._execute(item, t)
            return
        if item is None and parser.command_byte in QUERY_BYTES:
            if self._notes.on:
                self._took(byte, item, t)
            return
        self._hold = [(b, False) for b in before] + [(byte, framing_error)]
        self._heard.clear()  # noted when replayed

    def _abandon_frame(self) -> None:
        """MP-53 `error8_4`: drop the frame being parsed (at most its command byte, so never an
        overrun) through its CR; behind held input the drop waits its turn."""
        self.parser.abandon(None)
        if self._hold is not None:
            self._hold.append(ABANDON_FRAME)


def _bytes(held: list[tuple[int, bool]] | tuple[()]) -> bytes:
    """The bytes of held input (without the ABANDON_FRAME marker)."""
    return bytes(b for b, _ in held if b >= 0)
