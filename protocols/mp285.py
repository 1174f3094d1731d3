"""Sutter MP-285 / MP-285A external-control protocol: a pure codec (no I/O, no clock).

The wire format (docs/mp285.md): a command is one command byte, a fixed-length binary payload and a
CR; ^C (`03`) stands alone. Multi-byte values are little-endian, least significant byte first
(MP-11): positions are signed 32-bit microstep counts, the `V` word and status words unsigned 16-bit.
Every reply ends with CR and has a fixed length, so hosts must read by count (MP-10).

What is here:
- the command table (`COMMANDS`) and one dataclass per command with `encode()`;
- `FrameParser`, an incremental frame parser fed arbitrary chunks, which yields `Frame`, `CtrlC`,
  `StrayTerminator`, `BadFrame` and `BufferOverrun` items and exposes its state (command position,
  inside a frame, discarding) so a device model can treat bytes during a move differently;
- reply encoders/decoders: positions, the 32-byte `StatusBlock`, uploaded programs, error codes;
- the `V` word (`Velocity`) and the speed limits (`SpeedLimits`), microstep/micrometre conversion,
  one-line traffic summaries.

This module must not import from `emulator`: the client library and the conformance suite use it.
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields
from typing import ClassVar

# re-exported: MP-285 code rounds through this module (µm to µsteps, STEP fields, positions)
from protocols.rounding import round_half_away as round_half_away

CR = 0x0D
LF = 0x0A
CTRL_C = 0x03
AXES = ("X", "Y", "Z")

#: interrupt reply while a move is outstanding (MP-13, MP-48; the quick reference misprints it, MP-14)
ACK_INTERRUPT = 0x3D

POSITION_REPLY_LENGTH = 13
STATUS_LENGTH = 32
STATUS_REPLY_LENGTH = STATUS_LENGTH + 1
VECTOR_LENGTH = 16
MAX_PROGRAM = 10
MAX_VECTORS = 99
INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1

# ---- error codes (MP-19) ---------------------------------------------------------------------------


class ErrorCode(enum.IntEnum):
    """Error reply digits. '8' may be ORed with another code (MP-19)."""

    SP_OVERRUN = 0x30
    FRAME = 0x31
    BUFFER_OVERRUN = 0x32
    BAD_COMMAND = 0x34
    MOVE_INTERRUPTED = 0x38


ERROR_NAMES = {
    ErrorCode.SP_OVERRUN: "SP overrun",
    ErrorCode.FRAME: "frame error",
    ErrorCode.BUFFER_OVERRUN: "buffer overrun",
    ErrorCode.BAD_COMMAND: "bad command",
    ErrorCode.MOVE_INTERRUPTED: "move interrupted",
}


def combine_errors(*codes: int) -> int:
    """OR error digits together: '8' | '4' = '<' (MP-19)."""
    result = 0
    for code in codes:
        result |= code
    return result


def is_error_code(byte: int) -> bool:
    """True for '0', '1', '2', '4', '8' and '8' ORed with one of '0'-'4' ('9', ':', ';', '<')."""
    return byte in ERROR_NAMES or 0x38 <= byte <= 0x3C


def error_text(code: int) -> str:
    """`bad command`, or `move interrupted + bad command` for an ORed code."""
    if code in ERROR_NAMES:
        return ERROR_NAMES[ErrorCode(code)]
    if 0x39 <= code <= 0x3C:
        other = code & ~0x08
        name = ERROR_NAMES.get(ErrorCode(other)) if other in ERROR_NAMES else f"'{chr(other)}'"
        return f"move interrupted + {name}"
    return f"unknown error {code:02X}"


def error_reply(code: int) -> bytes:
    """`<digit> 0D`."""
    return bytes((code, CR))


# ---- little-endian helpers -------------------------------------------------------------------------


def pack_u16(value: int) -> bytes:
    return struct.pack("<H", value)


def unpack_u16(data: bytes) -> int:
    return int(struct.unpack("<H", data)[0])


def pack_xyz(x: int, y: int, z: int) -> bytes:
    return struct.pack("<iii", x, y, z)


def unpack_xyz(data: bytes) -> tuple[int, int, int]:
    return struct.unpack("<iii", data)


# ---- velocity word (MP-37) -------------------------------------------------------------------------

HIGH_RESOLUTION_BIT = 0x8000


@dataclass(frozen=True)
class Velocity:
    """The `V` word: bit 15 = high resolution (fine, 50 µsteps/step), bits 14-0 = speed in µm/s."""

    speed: int
    high: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.speed <= 0x7FFF:
            raise ValueError(f"speed {self.speed} does not fit 15 bits")

    @property
    def word(self) -> int:
        return (HIGH_RESOLUTION_BIT if self.high else 0) | self.speed

    @classmethod
    def from_word(cls, word: int) -> Velocity:
        return cls(word & 0x7FFF, bool(word & HIGH_RESOLUTION_BIT))

    def describe(self) -> str:
        return f"{self.speed} µm/s {'high' if self.high else 'low'} (word {self.word:04X})"


#: the fastest `V` speed in µm/s (MP-38): at low resolution by controller model, at high resolution
MAX_SPEED_LOW_UM_S = {"mp285": 6550, "mp285a": 3000}
MAX_SPEED_HIGH_UM_S = 1310


@dataclass(frozen=True)
class SpeedLimits:
    """The fastest speed in µm/s at low and at high resolution (MP-38)."""

    low: int
    high: int = MAX_SPEED_HIGH_UM_S

    @classmethod
    def of_model(cls, model: str) -> SpeedLimits:
        """A controller model's documented limits (`mp285` or `mp285a`)."""
        return cls(MAX_SPEED_LOW_UM_S[model])

    def limit(self, high: bool) -> int:
        return self.high if high else self.low

    def clamp(self, velocity: Velocity) -> Velocity:
        """The velocity in force after `V`: a speed over its resolution's limit is reduced to the
        limit (MP-39)."""
        return Velocity(min(velocity.speed, self.limit(velocity.high)), velocity.high)


# ---- program vectors (MP-16, MP-17) ----------------------------------------------------------------

#: descriptor of a move vector: wire bytes D0 07 00 00, i.e. little-endian 2000 (MP-17)
MOVE_DESCRIPTOR = 0x000007D0
PAUSE_DESCRIPTOR = 0


@dataclass(frozen=True)
class Vector:
    """One 16-byte program vector: descriptor (unsigned 32-bit, as read little-endian), X, Y, Z."""

    descriptor: int
    x: int = 0
    y: int = 0
    z: int = 0

    @classmethod
    def move(cls, x: int, y: int, z: int) -> Vector:
        return cls(MOVE_DESCRIPTOR, x, y, z)

    @classmethod
    def pause(cls) -> Vector:
        return cls(PAUSE_DESCRIPTOR)

    @property
    def is_move(self) -> bool:
        return self.descriptor == MOVE_DESCRIPTOR

    @property
    def is_pause(self) -> bool:
        return self.descriptor == PAUSE_DESCRIPTOR

    @property
    def xyz(self) -> tuple[int, int, int]:
        return (self.x, self.y, self.z)

    def pack(self) -> bytes:
        return struct.pack("<Iiii", self.descriptor, self.x, self.y, self.z)

    @classmethod
    def unpack(cls, data: bytes) -> Vector:
        return cls(*struct.unpack("<Iiii", data))

    def describe(self) -> str:
        if self.is_pause:
            return "pause"
        kind = "move" if self.is_move else f"type {self.descriptor:08X}"
        return f"{kind} ({self.x}, {self.y}, {self.z})"


def pack_vectors(vectors: Iterable[Vector]) -> bytes:
    return b"".join(v.pack() for v in vectors)


def unpack_vectors(data: bytes) -> tuple[Vector, ...]:
    return tuple(Vector.unpack(data[i : i + VECTOR_LENGTH]) for i in range(0, len(data), VECTOR_LENGTH))


# ---- commands (MP-13) ------------------------------------------------------------------------------


@dataclass(frozen=True)
class CommandSpec:
    """One row of the command table. `payload` None = variable (`d`); `reply` None = variable (`u`)."""

    byte: int
    name: str
    payload: int | None
    reply: int | None
    meaning: str

    @property
    def frame_length(self) -> int | None:
        """Command byte + payload + CR; None when the payload length is variable."""
        return None if self.payload is None else self.payload + 2


class Command:
    """Base of the command dataclasses: `encode()` gives the host frame."""

    BYTE: ClassVar[int]

    def payload(self) -> bytes:
        return b""

    def encode(self) -> bytes:
        return bytes((self.BYTE,)) + self.payload() + b"\r"

    def describe(self) -> str:
        return chr(self.BYTE)


@dataclass(frozen=True)
class GetPosition(Command):
    BYTE: ClassVar[int] = 0x63


@dataclass(frozen=True)
class Move(Command):
    """Target (absolute mode) or displacement (relative mode) in microsteps."""

    BYTE: ClassVar[int] = 0x6D
    x: int
    y: int
    z: int

    def payload(self) -> bytes:
        return pack_xyz(self.x, self.y, self.z)

    def describe(self) -> str:
        return f"m X={self.x} Y={self.y} Z={self.z} (µsteps)"


@dataclass(frozen=True)
class SetVelocity(Command):
    BYTE: ClassVar[int] = 0x56
    word: int

    @classmethod
    def of(cls, speed: int, high: bool = False) -> SetVelocity:
        return cls(Velocity(speed, high).word)

    @property
    def velocity(self) -> Velocity:
        return Velocity.from_word(self.word)

    def payload(self) -> bytes:
        return pack_u16(self.word)

    def describe(self) -> str:
        return f"V {self.velocity.describe()}"


@dataclass(frozen=True)
class SetOrigin(Command):
    BYTE: ClassVar[int] = 0x6F


@dataclass(frozen=True)
class Absolute(Command):
    BYTE: ClassVar[int] = 0x61


@dataclass(frozen=True)
class Relative(Command):
    BYTE: ClassVar[int] = 0x62


@dataclass(frozen=True)
class Interrupt(Command):
    """^C: the single byte 03, no payload, no terminator (MP-9)."""

    BYTE: ClassVar[int] = CTRL_C

    def encode(self) -> bytes:
        return bytes((CTRL_C,))

    def describe(self) -> str:
        return "^C"


@dataclass(frozen=True)
class Refresh(Command):
    BYTE: ClassVar[int] = 0x6E


@dataclass(frozen=True)
class Reset(Command):
    BYTE: ClassVar[int] = 0x72


@dataclass(frozen=True)
class GetStatus(Command):
    BYTE: ClassVar[int] = 0x73


@dataclass(frozen=True)
class Download(Command):
    """`d p n <vectors> CR` (MP-66). The program number is sent as given, even out of range."""

    BYTE: ClassVar[int] = 0x64
    program: int
    vectors: tuple[Vector, ...]

    def payload(self) -> bytes:
        return bytes((self.program, len(self.vectors))) + pack_vectors(self.vectors)

    def describe(self) -> str:
        return f"d program {self.program}, {len(self.vectors)} vector(s)"


@dataclass(frozen=True)
class Execute(Command):
    BYTE: ClassVar[int] = 0x6B
    program: int

    def payload(self) -> bytes:
        return bytes((self.program,))

    def describe(self) -> str:
        return f"k program {self.program}"


@dataclass(frozen=True)
class Upload(Command):
    BYTE: ClassVar[int] = 0x75
    program: int

    def payload(self) -> bytes:
        return bytes((self.program,))

    def describe(self) -> str:
        return f"u program {self.program}"


@dataclass(frozen=True)
class Continue(Command):
    BYTE: ClassVar[int] = 0x65


COMMANDS: dict[int, CommandSpec] = {
    spec.byte: spec
    for spec in (
        CommandSpec(0x63, "get position", 0, POSITION_REPLY_LENGTH, "X, Y, Z in µsteps"),
        CommandSpec(0x6D, "move", 12, 1, "move to X, Y, Z (absolute) or by X, Y, Z (relative)"),
        CommandSpec(0x56, "velocity/resolution", 2, 1, "V word: bit 15 resolution, bits 14-0 µm/s"),
        CommandSpec(0x6F, "set origin", 0, 1, "current position becomes (0, 0, 0)"),
        CommandSpec(0x61, "absolute mode", 0, 1, "m values are targets"),
        CommandSpec(0x62, "relative mode", 0, 1, "m values are displacements"),
        CommandSpec(0x6E, "refresh display", 0, 1, "redraw the display's coordinates"),
        CommandSpec(0x72, "reset", 0, 0, "soft reset, no reply"),
        CommandSpec(0x73, "status", 0, STATUS_REPLY_LENGTH, "32 status bytes"),
        CommandSpec(0x64, "download program", None, 1, "store program p of n vectors"),
        CommandSpec(0x6B, "execute program", 1, 1, "run program p"),
        CommandSpec(0x75, "upload program", 1, None, "n and the vectors of program p"),
        CommandSpec(0x65, "continue", 0, 1, "resume a paused program"),
    )
}

_DECODERS: dict[int, Callable[[bytes], Command]] = {
    GetPosition.BYTE: lambda p: GetPosition(),
    Move.BYTE: lambda p: Move(*unpack_xyz(p)),
    SetVelocity.BYTE: lambda p: SetVelocity(unpack_u16(p)),
    SetOrigin.BYTE: lambda p: SetOrigin(),
    Absolute.BYTE: lambda p: Absolute(),
    Relative.BYTE: lambda p: Relative(),
    Refresh.BYTE: lambda p: Refresh(),
    Reset.BYTE: lambda p: Reset(),
    GetStatus.BYTE: lambda p: GetStatus(),
    Download.BYTE: lambda p: Download(p[0], unpack_vectors(p[2:])),
    Execute.BYTE: lambda p: Execute(p[0]),
    Upload.BYTE: lambda p: Upload(p[0]),
    Continue.BYTE: lambda p: Continue(),
}


def decode_command(frame: bytes) -> Command:
    """A complete, well-formed frame (command byte, payload, CR) as its command dataclass."""
    if frame == bytes((CTRL_C,)):
        return Interrupt()
    return _DECODERS[frame[0]](frame[1:-1])


def reply_length(command: Command) -> int | None:
    """Bytes of the final reply when nothing goes wrong; None when it depends on the device (`u`, and
    ^C: `0D` idle, `3D 0D` during a move)."""
    if isinstance(command, Interrupt):
        return None
    return COMMANDS[command.BYTE].reply


# ---- replies ---------------------------------------------------------------------------------------


def encode_position(x: int, y: int, z: int) -> bytes:
    """The 13-byte `c` reply."""
    return pack_xyz(x, y, z) + b"\r"


def decode_position(data: bytes) -> tuple[int, int, int]:
    if len(data) != POSITION_REPLY_LENGTH or data[-1] != CR:
        raise ValueError(f"a position reply is 12 bytes + CR, got {data.hex(' ')}")
    return unpack_xyz(data[:12])


def encode_program(vectors: Iterable[Vector]) -> bytes:
    """The `u` reply: n, the vectors, CR (a never-downloaded program is `00 0D`, MP-72)."""
    vectors = tuple(vectors)
    return bytes((len(vectors),)) + pack_vectors(vectors) + b"\r"


def decode_program(data: bytes) -> tuple[Vector, ...]:
    if not data or len(data) != 2 + VECTOR_LENGTH * data[0] or data[-1] != CR:
        raise ValueError(f"an upload reply is n + 16n bytes + CR, got {len(data)} bytes")
    return unpack_vectors(data[1:-1])


_STATUS_LAYOUT = "<BBBBHHHHHBBHHHHHHHH"


@dataclass(frozen=True)
class StatusBlock:
    """The 32 bytes of the `s` reply (MP-60), in wire order."""

    flags: int
    udirx: int
    udiry: int
    udirz: int
    roe_vari: int
    uoffset: int
    urange: int
    pulse: int
    uspeed: int
    indevice: int
    flags_2: int
    jumpspd: int
    highspd: int
    dead: int
    watch_dog: int
    step_div: int
    step_mul: int
    xspeed: int
    version: int

    def pack(self) -> bytes:
        return struct.pack(_STATUS_LAYOUT, *(getattr(self, f.name) for f in fields(self)))

    def reply(self) -> bytes:
        """The 33-byte `s` reply (block + CR)."""
        return self.pack() + b"\r"

    @classmethod
    def unpack(cls, data: bytes) -> StatusBlock:
        """From the 32 bytes, or the 33-byte reply with its CR."""
        if len(data) == STATUS_REPLY_LENGTH and data[-1] == CR:
            data = data[:-1]
        if len(data) != STATUS_LENGTH:
            raise ValueError(f"a status block is 32 bytes (+ CR), got {len(data)}")
        return cls(*struct.unpack(_STATUS_LAYOUT, data))

    @property
    def velocity(self) -> Velocity:
        return Velocity.from_word(self.xspeed)

    @property
    def setup_number(self) -> int:
        return self.flags & 0x0F

    @property
    def roe_negative(self) -> bool:
        return bool(self.flags & 0x10)

    @property
    def step_mode_high(self) -> bool:
        """FLAGS_2 bit 2: 50 µsteps per step (MP-62)."""
        return bool(self.flags_2 & 0x04)

    def describe(self) -> str:
        version = f"{self.version // 100}.{self.version % 100:02d}"
        return (
            f"FLAGS {self.flags:02X}, XSPEED {self.velocity.describe()}, "
            f"STEP_DIV/MUL {self.step_div}/{self.step_mul}, VERSION {version}"
        )


# ---- units (MP-28) ---------------------------------------------------------------------------------

#: microsteps per micrometre of X and Y by device type (Z: `z_usteps_per_um`, 25 unless customised)
XY_USTEPS_PER_UM = {"mp285": 25, "mt800": 20}
DEFAULT_Z_USTEPS_PER_UM = 25


def axis_factors(device_type: str, z_usteps_per_um: float = DEFAULT_Z_USTEPS_PER_UM) -> tuple[float, ...]:
    """µsteps per µm of X, Y, Z."""
    xy = XY_USTEPS_PER_UM[device_type]
    return (xy, xy, z_usteps_per_um)


def usteps_to_um(usteps: int, usteps_per_um: float) -> float:
    return usteps / usteps_per_um


def um_to_usteps(um: float, usteps_per_um: float) -> int:
    return round_half_away(um * usteps_per_um)


def step_fields(xy_usteps_per_um: int, fmt: str) -> tuple[int, int]:
    """STEP_DIV and STEP_MUL (MP-63): `mp285` = (µsteps/µm, µm/µstep × 100); `mp285a` = nm per 10
    µsteps, twice."""
    if fmt == "mp285":
        return xy_usteps_per_um, round_half_away(100 / xy_usteps_per_um)
    nm = round_half_away(10_000 / xy_usteps_per_um)
    return nm, nm


# ---- the frame parser (MP-8 ... MP-26) -------------------------------------------------------------


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


# ---- traffic summaries -----------------------------------------------------------------------------


def describe_item(item: Item) -> str:
    """One line for an item of the frame parser, e.g. `m X=1200 Y=-40 Z=0 (µsteps)`."""
    if isinstance(item, Frame):
        return item.command.describe()
    if isinstance(item, CtrlC):
        return "^C"
    if isinstance(item, StrayTerminator):
        return "stray CR" if item.byte == CR else "stray LF"
    if isinstance(item, BadFrame):
        owed = "no reply owed" if item.error is None else f"error '{chr(item.error)}' owed"
        return f"CR ending a bad frame ({owed})"
    return "buffer overrun: error '2'"


def _hex(data: bytes, limit: int = 48) -> str:
    text = data[:limit].hex(" ").upper()
    return text + (" …" if len(data) > limit else "")


def summarize_device(data: bytes, to: str | None = None) -> str:
    """One line for bytes the device sent, interpreted by length and content (replies carry no
    type), e.g. `reply: position X=… Y=… Z=…` or `error '4' bad command`; given the command they
    answer, `to`, e.g. `reply to c: position X=… Y=… Z=…`."""
    text = _describe_device(data)
    return text if to is None else f"reply to {to}: {text.removeprefix('reply: ')}"


def _describe_device(data: bytes) -> str:
    if data == b"\r":
        return "reply: CR (done)"
    if data == bytes((ACK_INTERRUPT,)):
        return "reply: '=' (interrupt acknowledged)"
    if len(data) == 2 and data[1] == CR and is_error_code(data[0]):
        return f"error '{chr(data[0])}' {error_text(data[0])}"
    if len(data) == POSITION_REPLY_LENGTH and data[-1] == CR:
        x, y, z = unpack_xyz(data[:12])
        return f"reply: position X={x} Y={y} Z={z} (µsteps)"
    if len(data) == STATUS_REPLY_LENGTH and data[-1] == CR:
        return f"reply: status {StatusBlock.unpack(data).describe()}"
    if len(data) >= 2 and data[-1] == CR and len(data) == 2 + VECTOR_LENGTH * data[0]:
        vectors = decode_program(data)
        return f"reply: program of {len(vectors)} vector(s): {', '.join(v.describe() for v in vectors)}"
    return f"{len(data)} byte(s): {_hex(data)}"
