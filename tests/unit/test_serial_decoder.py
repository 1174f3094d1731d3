"""The serial transport's line-error decoding: the kernel's PARMRK marks (FF FF a data FF, FF 00 X
a character X received with a framing or parity error, FF 00 00 a break) undone however the reads
split them; which kind a marked character was; and the runner's bookkeeping of error characters
among queued input."""

from __future__ import annotations

import itertools

import pytest

from emulator.device import FRAMING_ERROR, PARITY_ERROR
from emulator.hosting.line_errors import LineErrors
from emulator.hosting.transports.serial_port import LineError, Piece, error_kind, unmark

#: data with FFs (a data FF is doubled), 00s, a break and errors on FF, 00 and ordinary characters
STREAM: list[Piece] = [
    b"\x63\xff\x00\x0d",
    LineError(0x00),
    LineError(0xFF),
    b"\xff",
    LineError(0x1E),
    LineError(0x00),
    b"\x00\xff\xff\x41",
]


def marked(pieces: list[Piece]) -> bytes:
    """What a PARMRK port gives for `pieces`."""
    out = bytearray()
    for piece in pieces:
        if isinstance(piece, LineError):
            out += bytes((0xFF, 0x00, piece.byte))
        else:
            out += piece.replace(b"\xff", b"\xff\xff")
    return bytes(out)


def merged(pieces: list[Piece]) -> list[Piece]:
    """Adjacent data runs joined (reads may split a run anywhere)."""
    out: list[Piece] = []
    for piece in pieces:
        if isinstance(piece, bytes) and out and isinstance(out[-1], bytes):
            out[-1] += piece
        elif piece != b"":
            out.append(piece)
    return out


def decode_in_reads(raw: bytes, cuts: tuple[int, ...]) -> list[Piece]:
    pieces: list[Piece] = []
    held = b""
    for start, end in itertools.pairwise((0, *cuts, len(raw))):
        got, held = unmark(raw[start:end], held)
        pieces += got
    assert held == b"", "a complete stream leaves no mark unfinished"
    return merged(pieces)


def test_one_read_gives_the_pieces_back() -> None:
    assert decode_in_reads(marked(STREAM), ()) == merged(STREAM)


def test_every_split_of_the_reads_gives_the_same_pieces() -> None:
    raw = marked(STREAM)
    for count in (1, 2, 3):
        for cuts in itertools.combinations(range(1, len(raw)), count):
            assert decode_in_reads(raw, cuts) == merged(STREAM), cuts


def test_byte_by_byte_reads() -> None:
    raw = marked(STREAM)
    assert decode_in_reads(raw, tuple(range(1, len(raw)))) == merged(STREAM)


@pytest.mark.parametrize(
    ("raw", "pieces", "held"),
    [
        (b"", [], b""),
        (b"abc", [b"abc"], b""),
        (b"ab\xff", [b"ab"], b"\xff"),
        (b"ab\xff\x00", [b"ab"], b"\xff\x00"),
        (b"\xff\x00\x00", [LineError(0)], b""),  # a break
        (b"\xff\xff", [b"\xff"], b""),
    ],
)
def test_unfinished_marks_are_held_for_the_next_read(raw: bytes, pieces: list[Piece], held: bytes) -> None:
    assert unmark(raw) == (pieces, held)


def test_an_undoubled_ff_is_data() -> None:
    """While pyserial reconfigures the port PARMRK is briefly off: a data FF comes single."""
    assert unmark(b"\xff\x41\xff\xff") == ([b"\xff\x41\xff"], b"")


def test_error_kind_from_the_counters() -> None:
    """Without parity every mark is a framing error (a break is one too); with parity, a parity
    error only when the UART's counters say parity alone rose."""
    assert error_kind(False, (0, 0, 0), (0, 5, 0)) == FRAMING_ERROR
    assert error_kind(True, (0, 0, 0), (0, 1, 0)) == PARITY_ERROR
    assert error_kind(True, (0, 0, 0), (1, 1, 0)) == FRAMING_ERROR
    assert error_kind(True, (0, 0, 0), (0, 1, 1)) == FRAMING_ERROR
    assert error_kind(True, None, None) == FRAMING_ERROR  # no counters (a pty, some adapters)


def test_line_errors_follow_their_place_in_the_queue() -> None:
    errors = LineErrors()
    errors.add(2, FRAMING_ERROR)
    errors.add(5, PARITY_ERROR)
    assert errors.split(b"ab") == [(b"ab", None)]
    assert errors.split(b"cde") == [(b"c", FRAMING_ERROR), (b"de", None)]
    assert errors.split(b"fg") == [(b"f", PARITY_ERROR), (b"g", None)]
    assert not errors
    assert errors.split(b"h") == [(b"h", None)]


def test_line_errors_split_one_run_into_several_pieces() -> None:
    errors = LineErrors()
    for position in (0, 1, 3):
        errors.add(position, FRAMING_ERROR)
    assert errors.split(b"abcde") == [
        (b"a", FRAMING_ERROR),
        (b"b", FRAMING_ERROR),
        (b"c", None),
        (b"d", FRAMING_ERROR),
        (b"e", None),
    ]
