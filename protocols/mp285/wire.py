"""MP-285 wire basics: control bytes, fixed reply lengths and little-endian packing.

A command is one command byte, a fixed-length binary payload and a CR; ^C (`03`) stands alone.
Multi-byte values are little-endian, least significant byte first (MP-11): positions are signed
32-bit microstep counts, the `V` word and status words unsigned 16-bit. Every reply ends with CR and
has a fixed length, so hosts must read by count (MP-10).
"""

from __future__ import annotations

import struct

CR = 0x0D
LF = 0x0A
CTRL_C = 0x03
AXES = ("X", "Y", "Z")

#: interrupt reply while a move is outstanding (MP-13, MP-48; the quick reference misprints it, MP-14)
ACK_INTERRUPT = 0x3D

POSITION_REPLY_LENGTH = 13
STATUS_LENGTH = 32
STATUS_REPLY_LENGTH = STATUS_LENGTH + 1
INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1


def pack_u16(value: int) -> bytes:
    return struct.pack("<H", value)


def unpack_u16(data: bytes) -> int:
    return int(struct.unpack("<H", data)[0])


def pack_xyz(x: int, y: int, z: int) -> bytes:
    return struct.pack("<iii", x, y, z)


def unpack_xyz(data: bytes) -> tuple[int, int, int]:
    return struct.unpack("<iii", data)
