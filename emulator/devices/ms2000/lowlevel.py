"""Low-level binary mode (§8): frames addressed by axis id, numbers in tenths of a micron of user
position, 24-bit two's complement least significant byte first (MS-120, MS-121). While explaining,
each frame is noted with its bytes (`frame`, or `stray` for one the controller ignores)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

from emulator.device import FRAME, STRAY, Notes
from emulator.devices.ms2000.status import status_byte
from protocols.ms2000 import LLCommand, LLFrame, LLFrameDecoder, decode_int24, encode_int24
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.sections import Ms2000Knobs

TENTHS_PER_MM = 10000
#: default step of `+`/`-` in tenths of a micron (10 µm) [choice] (MS-121)
DEFAULT_INCREMENT = 100


class LowLevelOwner(Protocol):
    """All low-level mode uses of its controller."""

    @property
    def axes(self) -> Sequence[Axis]: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def notes(self) -> Notes:
        """Input notes for the traffic log, kept only while explaining."""

    def send_raw(self, data: bytes, t: float, to: str | None = None) -> None: ...

    def start_moves(self, goals: list[tuple[Axis, float]], t: float) -> None: ...

    def relative_goal(self, axis: Axis, delta_mm: float, t: float) -> float: ...

    def enable_motor(self, axis: Axis, t: float) -> None: ...

    def set_manual_enabled(self, axis: Axis, enabled: bool, t: float) -> None: ...


class LowLevel:
    def __init__(self, controller: LowLevelOwner) -> None:
        self.controller = controller
        self.decoder = LLFrameDecoder()
        self.increments: dict[str, int] = {}
        #: bytes of the frame being decoded (while explaining)
        self._heard = bytearray()

    def reset(self) -> None:
        self.decoder.axis_ids = {a.s.ll_id for a in self.controller.axes}
        self.decoder.reset()
        self._heard.clear()
        self.increments = {a.hw_letter: DEFAULT_INCREMENT for a in self.controller.axes}

    def drop(self, t: float, kind: str, why: str) -> None:
        """The frame being decoded is discarded (noted as `kind` for `why`)."""
        self.decoder.reset()
        if self._heard:
            self.controller.notes.rx(t, kind, bytes(self._heard), why)
            self._heard.clear()

    def feed(self, byte: int, t: float) -> None:
        frame = self.decoder.feed(byte)
        if self.controller.notes.on:
            self._heard.append(byte)
            if frame is not None:
                self.controller.notes.rx(
                    t, FRAME if frame.known else STRAY, bytes(self._heard), describe(frame)
                )
                self._heard.clear()
        if frame is not None and frame.known:
            self.execute(frame, t)

    def _tenths(self, axis: Axis, t: float) -> int:
        return round_half_away(axis.user_mm(t) * TENTHS_PER_MM)

    def execute(self, frame: LLFrame, t: float) -> None:
        axis = next((a for a in self.controller.axes if a.s.ll_id == frame.axis_id), None)
        if axis is None:
            return
        controller = self.controller
        command = LLCommand(frame.command)
        status = status_byte(axis, t, controller.knobs.status_bit5_up_is_one, low_level=True)
        to = describe(frame) if controller.notes.on else ""
        if command is LLCommand.BUSY:
            controller.send_raw(b"B" if axis.busy(t) else b"b", t, to)
        elif command is LLCommand.POSITION:
            controller.send_raw(encode_int24(self._tenths(axis, t)), t, to)
        elif command is LLCommand.POSITION_STATUS:
            controller.send_raw(encode_int24(self._tenths(axis, t)) + bytes([status]), t, to)
        elif command is LLCommand.STATUS:
            controller.send_raw(bytes([status]), t, to)
        elif command is LLCommand.READ_INCREMENT:
            controller.send_raw(encode_int24(self.increments[axis.hw_letter]), t, to)
        elif command is LLCommand.START_MOTOR:
            controller.enable_motor(axis, t)
        elif command in (LLCommand.JOYSTICK_ON, LLCommand.JOYSTICK_OFF):
            controller.set_manual_enabled(axis, command is LLCommand.JOYSTICK_ON, t)
        elif command is LLCommand.WRITE_INCREMENT:
            self.increments[axis.hw_letter] = decode_int24(frame.data)
        elif command is LLCommand.MOVE_TO:
            goal = axis.counts_of(decode_int24(frame.data) / TENTHS_PER_MM)
            controller.start_moves([(axis, goal)], t)
        elif command in (LLCommand.STEP_UP, LLCommand.STEP_DOWN):
            sign = 1 if command is LLCommand.STEP_UP else -1
            step_mm = sign * self.increments[axis.hw_letter] / TENTHS_PER_MM
            controller.start_moves([(axis, controller.relative_goal(axis, step_mm, t))], t)


def describe(frame: LLFrame) -> str:
    """A low-level frame for the traffic log, e.g. `low-level a (POSITION) to axis 18`."""
    if frame.command in LLCommand._value2member_map_:
        name = f"{chr(frame.command)} ({LLCommand(frame.command).name})"
    else:
        name = f"{frame.command:02X}"
    data = f" data {frame.data.hex(' ')}" if frame.data else ""
    ignored = "" if frame.known else ", ignored (MS-123)"
    return f"low-level {name} to axis {frame.axis_id:02X}{data}{ignored}"
