"""MP-285 program vectors: the 16-byte move/pause records of `d` and `u` (MP-16, MP-17)."""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass

VECTOR_LENGTH = 16
MAX_PROGRAM = 10
MAX_VECTORS = 99

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
