"""What the MP-285 makes of each character it accepts (docs/mp285.md §2, §3, §7).

Frames are delimited by the protocol's `FrameParser` and each completed item is handed to the
device. While an `m`, `k` or `e` is outstanding, bytes are treated per §7: ^C halts the move and is
acknowledged at once (MP-48), other bytes may interrupt it (MP-50, MP-51, MP-53), `c`/`s` frames are
answered at once and anything else is held, with all that follows, until the final reply (MP-52).
A frame left incomplete arms the lock-up timer (MP-80).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from emulator.devices.mp285.commands import QUERY_BYTES
from emulator.devices.mp285.motion import Halt, Run
from protocols import mp285 as proto
from protocols.mp285 import CR, CTRL_C, LF, Frame, FrameParser, Item, ParseState

#: stands in held input for the `error8_4` drop of the frame being parsed, so that the drop is
#: replayed in its turn (MP-53, MP-52)
ABANDON_FRAME = (-1, False)
ACK = bytes((proto.ACK_INTERRUPT,))


class Receiver:
    """The frame layer: parser, held input and the lock-up timer, with what the device lends it:
    `execute(item, t)` runs a parsed item, `send(t, data, reply)` transmits, `current_run()` is the
    outstanding run (None unless MOVING)."""

    def __init__(
        self,
        knobs: Any,
        execute: Callable[[Item, float], None],
        send: Callable[[float, bytes, bool], None],
        current_run: Callable[[], Run | None],
    ) -> None:
        self.parser = FrameParser(knobs.input_buffer_size)
        #: when an incomplete frame locks the controller up (MP-80), None when not armed
        self.lockup_at: float | None = None
        self._execute = execute
        self._send = send
        self._current_run = current_run
        self._lockup_s: float | None = knobs.lockup_incomplete_frame_s
        self._settle_s: float = knobs.settle_s
        self._drop_interrupting = knobs.move_interrupt_reply == "error8_4"
        self._terminators_interrupt: bool = knobs.terminators_interrupt_move
        self._queries_interrupt: bool = knobs.query_interrupts_move
        self._hold: list[tuple[int, bool]] | None = None
        self._epoch = 0  # bumped whenever queued input is thrown away (reset, power cycle, crash)

    def dispatch(self, byte: int, framing_error: bool, t: float, run: Run | None) -> None:
        """One accepted character at `t`; `run`: the outstanding run, None unless MOVING."""
        parser = self.parser
        if run is not None:
            self._byte_during_move(byte, framing_error, t, run)
        else:
            item = parser.feed_byte(byte, framing_error)
            if item is not None:
                self._execute(item, t)
        limit = self._lockup_s
        in_frame = parser.state is not ParseState.COMMAND
        self.lockup_at = t + limit if limit is not None and in_frame else None  # MP-80

    def drop(self) -> None:
        """Partial frames and held input are thrown away (MP-57, MP-76, MP-77)."""
        self._epoch += 1
        self.parser.reset()
        self._hold = None
        self.lockup_at = None

    def forget_frame(self) -> None:
        """The frame being parsed is lost (MP-7 overrun)."""
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
        for byte, framing_error in held:
            if self._epoch != epoch:
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
                return
        self._frame_during_move(byte, framing_error, t)

    def _ctrl_c_during_move(self, run: Run, t: float) -> None:
        self._send(t, ACK, False)
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
            if item is not None:
                self._execute(item, t)
            return
        before = parser.frame_bytes
        item = parser.feed_byte(byte, framing_error)
        if isinstance(item, Frame) and item.raw[0] in QUERY_BYTES:
            self._execute(item, t)
            return
        if item is None and parser.command_byte in QUERY_BYTES:
            return
        self._hold = [(b, False) for b in before] + [(byte, framing_error)]

    def _abandon_frame(self) -> None:
        """MP-53 `error8_4`: drop the frame being parsed (at most its command byte, so never an
        overrun) through its CR; behind held input the drop waits its turn."""
        self.parser.abandon(None)
        if self._hold is not None:
            self._hold.append(ABANDON_FRAME)
