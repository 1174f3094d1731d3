"""MP-285 commands: the command table (MP-13), one dataclass per command with `encode()`, decoding.

A command is one command byte, a fixed-length payload and a CR; `d` has a variable payload and `u`
a variable reply. ^C (`03`) is a single byte with no payload and no terminator (MP-9).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

from protocols.mp285.speed import Velocity
from protocols.mp285.vectors import Vector, pack_vectors, unpack_vectors
from protocols.mp285.wire import (
    CTRL_C,
    POSITION_REPLY_LENGTH,
    STATUS_REPLY_LENGTH,
    pack_u16,
    pack_xyz,
    unpack_u16,
    unpack_xyz,
)


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
