"""MP-285 status block: the 32 bytes of the `s` reply (MP-60, MP-62)."""

from __future__ import annotations

import struct
from dataclasses import dataclass, fields

from protocols.mp285.speed import Velocity
from protocols.mp285.wire import CR, STATUS_LENGTH, STATUS_REPLY_LENGTH

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
