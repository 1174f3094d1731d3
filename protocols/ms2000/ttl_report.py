"""TTL REPORT frames (MS-TTLREP-2, MS-TTLREP-4): what the controller sends on its auxiliary port on
each IN0 edge with `TTL X=6`.

Binary (the default): for each motor axis in hardware order its low-level axis id byte (`LL`), then
its position in encoder counts as a signed 32-bit integer, least significant byte first; then CR.
A three-axis frame is 16 bytes. The CR is not a delimiter (a count may contain 0x0D): a frame is
recognised by its length, 5 bytes per axis plus one. ASCII (on request): the positions as `W`
prints them, one line.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

#: bytes per axis in a binary frame: id byte + int32
AXIS_BYTES = 5
FRAME_END = b"\r"
#: the factory low-level ids of X, Y, Z, F (MS-114); `LL` changes them
DEFAULT_AXIS_IDS = {0x18: "X", 0x19: "Y", 0x1A: "Z", 0x1B: "F"}
_COUNTS = struct.Struct("<i")


class TtlReportError(ValueError):
    """Bytes that are not a TTL REPORT frame."""


@dataclass(frozen=True)
class TtlReport:
    """One decoded frame: (low-level axis id, encoder counts) per motor axis, in hardware order."""

    positions: tuple[tuple[int, int], ...]

    def by_axis(self, names: dict[int, str] | None = None) -> dict[str, int]:
        """Counts by axis letter (factory ids unless `names` maps the ids an `LL` set)."""
        names = DEFAULT_AXIS_IDS if names is None else names
        return {names.get(axis_id, f"#{axis_id}"): counts for axis_id, counts in self.positions}


def frame_length(axes: int) -> int:
    """Bytes in a binary frame of `axes` motor axes."""
    return axes * AXIS_BYTES + len(FRAME_END)


def encode(positions: Sequence[tuple[int, int]]) -> bytes:
    """A binary frame. Counts outside 32 bits wrap, as the controller's 32-bit register does."""
    out = bytearray()
    for axis_id, counts in positions:
        wrapped = (counts + 2**31) % 2**32 - 2**31
        out.append(axis_id & 0xFF)
        out += _COUNTS.pack(wrapped)
    return bytes(out + FRAME_END)


def decode(frame: bytes) -> TtlReport:
    """A binary frame (its CR included) as a `TtlReport`."""
    if len(frame) % AXIS_BYTES != len(FRAME_END) or not frame.endswith(FRAME_END):
        raise TtlReportError(f"not a TTL REPORT frame (5 bytes per axis, then CR): {frame!r}")
    body = frame[: -len(FRAME_END)]
    return TtlReport(
        tuple((body[i], _COUNTS.unpack_from(body, i + 1)[0]) for i in range(0, len(body), AXIS_BYTES))
    )


def parse_line(line: str) -> tuple[float, ...]:
    """An ASCII report line (`1000 -505 0`, terminator removed or not) as positions in units."""
    try:
        return tuple(float(item) for item in line.split())
    except ValueError:
        raise TtlReportError(f"not a TTL REPORT line: {line!r}") from None
