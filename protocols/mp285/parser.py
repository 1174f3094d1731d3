"""MP-285 frame parser: delimits host frames byte by byte and yields what they complete (MP-8 ... MP-26).

`FrameParser` is fed arbitrary chunks and yields `Frame`, `CtrlC`, `StrayTerminator`, `BadFrame` and
`BufferOverrun` items; it exposes its state (command position, inside a frame, discarding) so a
device model can treat bytes during a move differently.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from protocols.mp285.commands import COMMANDS, Command, decode_command
from protocols.mp285.errors import ErrorCode
from protocols.mp285.vectors import MAX_VECTORS, VECTOR_LENGTH
from protocols.mp285.wire import CR, CTRL_C, LF


class ParseState(enum.Enum):
    COMMAND = "command"  # the next byte is in command position
    COLLECTING = "collecting"  # inside a frame
    DISCARDING = "discarding"  # after a bad byte, until a clean CR


@dataclass(frozen=True)
class Frame:
    """A complete, well-formed frame."""

    command: Command
    raw: bytes


@dataclass(frozen=True)
class CtrlC:
    """^C in command position (MP-9)."""


@dataclass(frozen=True)
class StrayTerminator:
    """A lone CR or LF in command position (MP-20)."""

    byte: int


@dataclass(frozen=True)
class BadFrame:
    """The CR that ends DISCARDING. `error` is the reply digit owed, None when nothing is owed
    (after a buffer overrun, MP-23, or a silently abandoned frame, MP-53)."""

    error: int | None


@dataclass(frozen=True)
class BufferOverrun:
    """More than `input_buffer_size` bytes of a bad frame without a CR: reply `32 0D` now (MP-23)."""


Item = Frame | CtrlC | StrayTerminator | BadFrame | BufferOverrun

DOWNLOAD_HEADER = 3  # `d`, program number, vector count


class FrameParser:
    """Delimits frames byte by byte; chunking never changes the result.

    A byte with a framing error (MP-6) is never data: it makes the frame bad with error '1'. While
    DISCARDING every byte but a clean CR is dropped (^C included); the first error recorded wins,
    except that '1' replaces a pending '4' (MP-24).
    """

    def __init__(self, input_buffer_size: int = 64) -> None:
        self.input_buffer_size = input_buffer_size
        self.state = ParseState.COMMAND
        self._frame = bytearray()
        self._length: int | None = None
        self._error: int | None = None
        self._count = 0

    def reset(self) -> None:
        """Drop any partial frame and pending error: back to command position."""
        self.state = ParseState.COMMAND
        self._frame.clear()
        self._length = None
        self._error = None
        self._count = 0

    @property
    def frame_bytes(self) -> bytes:
        """Bytes of the frame being collected (empty unless COLLECTING)."""
        return bytes(self._frame)

    @property
    def command_byte(self) -> int | None:
        return self._frame[0] if self.state is ParseState.COLLECTING else None

    @property
    def expects_terminator(self) -> bool:
        """True when the next byte sits in the frame's terminator position."""
        return (
            self.state is ParseState.COLLECTING
            and self._length is not None
            and len(self._frame) == self._length - 1
        )

    @property
    def pending_error(self) -> int | None:
        return self._error if self.state is ParseState.DISCARDING else None

    def feed(self, data: bytes) -> list[Item]:
        """Feed clean bytes; returns the items they complete, in order."""
        items = []
        for byte in data:
            item = self.feed_byte(byte)
            if item is not None:
                items.append(item)
        return items

    def feed_byte(self, byte: int, framing_error: bool = False) -> Item | None:
        if self.state is ParseState.DISCARDING:
            return self._discard(byte, framing_error)
        if self.state is ParseState.COMMAND:
            return self._command(byte, framing_error)
        return self._collect(byte, framing_error)

    def abandon(self, error: int | None) -> BufferOverrun | None:
        """Make the current frame (or the frame the next byte would start) bad: discard through the
        next clean CR, which then owes `error` (None: nothing)."""
        return self._start_discarding(len(self._frame), error)

    def _command(self, byte: int, framing_error: bool) -> Item | None:
        if framing_error:
            return self._start_discarding(1, ErrorCode.FRAME)
        if byte == CTRL_C:
            return CtrlC()
        if byte in (CR, LF):
            return StrayTerminator(byte)
        spec = COMMANDS.get(byte)
        if spec is None:
            return self._start_discarding(1, ErrorCode.BAD_COMMAND)  # MP-21
        self.state = ParseState.COLLECTING
        self._frame = bytearray((byte,))
        self._length = spec.frame_length
        return self._complete_if_full()

    def _collect(self, byte: int, framing_error: bool) -> Item | None:
        if framing_error:
            return self._start_discarding(len(self._frame) + 1, ErrorCode.FRAME)
        if self.expects_terminator and byte != CR:
            return self._start_discarding(len(self._frame) + 1, ErrorCode.BAD_COMMAND)  # MP-22
        self._frame.append(byte)
        if self._length is None and len(self._frame) == DOWNLOAD_HEADER:
            count = self._frame[2]
            if not 1 <= count <= MAX_VECTORS:
                return self._start_discarding(len(self._frame), ErrorCode.BAD_COMMAND)  # MP-67
            self._length = DOWNLOAD_HEADER + VECTOR_LENGTH * count + 1
        return self._complete_if_full()

    def _complete_if_full(self) -> Frame | None:
        if self._length is None or len(self._frame) < self._length:
            return None
        raw = bytes(self._frame)
        self.reset()
        return Frame(decode_command(raw), raw)

    def _start_discarding(self, count: int, error: int | None) -> BufferOverrun | None:
        self.state = ParseState.DISCARDING
        self._frame.clear()
        self._length = None
        self._error = error
        self._count = count
        return self._check_overrun()

    def _discard(self, byte: int, framing_error: bool) -> Item | None:
        if byte == CR and not framing_error:
            error = self._error
            self.reset()
            return BadFrame(error)
        if framing_error and self._error == ErrorCode.BAD_COMMAND:
            self._error = ErrorCode.FRAME
        self._count += 1
        return self._check_overrun()

    def _check_overrun(self) -> BufferOverrun | None:
        if self._count <= self.input_buffer_size:
            return None
        self._count = 0
        self._error = None  # the CR that finally ends DISCARDING owes nothing (MP-23)
        return BufferOverrun()
