"""MP-285 position and program replies: the 13-byte `c` reply and the `u` upload reply."""

from __future__ import annotations

from collections.abc import Iterable

from protocols.mp285.vectors import VECTOR_LENGTH, Vector, pack_vectors, unpack_vectors
from protocols.mp285.wire import CR, POSITION_REPLY_LENGTH, pack_xyz, unpack_xyz


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
