"""MS2000 low-level binary mode (§8): control sequences, host frames and 24-bit numbers (MS-120…MS-123)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum

CONTROL = 0xFF
LL_TERMINATOR = 0x3A
INT24_MAX = (1 << 23) - 1


class LLCommand(IntEnum):
    BUSY = ord("?")
    POSITION = ord("a")
    POSITION_STATUS = ord("l")
    STATUS = ord("~")
    START_MOTOR = ord("G")
    JOYSTICK_ON = ord("J")
    JOYSTICK_OFF = ord("K")
    MOVE_TO = ord("T")
    STEP_UP = ord("+")
    STEP_DOWN = ord("-")
    WRITE_INCREMENT = ord("D")
    READ_INCREMENT = ord("d")


LL_WRITES = frozenset({LLCommand.MOVE_TO, LLCommand.WRITE_INCREMENT})
#: reply length of each read command (MS-121)
LL_REPLY_LENGTH = {
    LLCommand.BUSY: 1,
    LLCommand.POSITION: 3,
    LLCommand.POSITION_STATUS: 4,
    LLCommand.STATUS: 1,
    LLCommand.READ_INCREMENT: 3,
}
#: the n a host sends with each read: the reply length, except `l` (3 position bytes, the status
#: byte comes on top) and `?` (0), as in ASI's examples (MS-120)
LL_READ_N = {
    LLCommand.BUSY: 0,
    LLCommand.POSITION: 3,
    LLCommand.POSITION_STATUS: 3,
    LLCommand.STATUS: 1,
    LLCommand.READ_INCREMENT: 3,
}


def encode_int24(value: int) -> bytes:
    """24-bit two's complement, least significant byte first; values outside ±8388607 wrap (MS-120)."""
    return (int(value) & 0xFFFFFF).to_bytes(3, "little")


def decode_int24(data: bytes) -> int:
    value = int.from_bytes(data[:3], "little")
    return value - (1 << 24) if value & 0x800000 else value


def encode_ll_frame(axis_id: int, command: int, value: int | None = None, n: int | None = None) -> bytes:
    """A host frame: axis id, command, n, data, `:`. Write commands carry `value` as 3 data bytes;
    reads send their reply length as n unless `n` says otherwise (MS-120)."""
    if value is not None:
        data = encode_int24(value)
        return bytes([axis_id, command, len(data)]) + data + b":"
    length = LL_READ_N.get(LLCommand(command), 0) if n is None else n
    return bytes([axis_id, command, length]) + b":"


@dataclass(frozen=True)
class LLFrame:
    """A decoded host frame. `known` is False for frames the controller consumes and ignores."""

    axis_id: int
    command: int
    data: bytes = b""
    known: bool = True


class LLFrameDecoder:
    """Incremental decoder of host frames (MS-120, MS-123). `feed(byte)` returns a frame when one
    completes. `axis_ids` are the ids in use; frames for other ids are consumed up to `:` and
    returned with `known=False`."""

    def __init__(self, axis_ids: Iterable[int] = ()) -> None:
        self.axis_ids = set(axis_ids)
        self.reset()

    def reset(self) -> None:
        self._state = "axis"
        self._axis = 0
        self._command = 0
        self._need = 0
        self._data = bytearray()
        self._ignore = False

    def feed(self, byte: int) -> LLFrame | None:
        state = self._state
        if state == "axis":
            self._axis = byte
            self._ignore = byte not in self.axis_ids
            self._state = "skip" if self._ignore else "command"
            return None
        if state == "command":
            self._command = byte
            known = byte in LLCommand._value2member_map_
            if not known:
                self._ignore = True
                self._state = "skip"
            else:
                self._state = "count"
            return None
        if state == "count":
            if self._command in LL_WRITES:
                self._need = byte
                self._data.clear()
                self._state = "data" if byte else "end"
                return None
            # reads and zero-data commands: n (if any) and stray bytes up to `:` are ignored
            if byte == LL_TERMINATOR:
                return self._finish()
            self._state = "skip"
            return None
        if state == "data":
            self._data.append(byte)
            if len(self._data) >= self._need:
                self._state = "end"
            return None
        if state == "end":
            if byte == LL_TERMINATOR:
                if len(self._data) != 3:
                    self._ignore = True
                return self._finish()
            self._ignore = True
            self._state = "skip"
            return None
        # skip: consume up to the next terminator
        if byte == LL_TERMINATOR:
            return self._finish()
        return None

    def _finish(self) -> LLFrame:
        frame_ = LLFrame(self._axis, self._command, bytes(self._data), not self._ignore)
        self.reset()
        return frame_
