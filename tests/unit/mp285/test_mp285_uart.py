"""emulator/uart.py: the MP-6 bit-level model of a mismatched serial line."""

from __future__ import annotations

from fractions import Fraction

import pytest

from emulator.device import HostLine, LineSettings
from emulator.uart import Char, Framing, Wire, garble

DEVICE = Framing(9600)


def decoded(chars: list[Char]) -> list[tuple[int, bool]]:
    return [(c.value, c.framing_error) for c in chars]


@pytest.mark.parametrize(
    ("data", "sender", "receiver", "expected"),
    [
        (b"c\r", Framing(19200), DEVICE, [(0x91, False)]),  # MP-6: a host at twice the baud
        (b"c\r", Framing(4800), DEVICE, [(0x1E, True), (0x66, True), (0x80, False)]),  # MP-6: at half
        (b"\r", DEVICE, Framing(19200), [(0xE6, False), (0x80, False)]),  # MP-6
        (b"\x00", DEVICE, Framing(19200), [(0x00, True)]),  # MP-6: delivered as 00
        (b"c\r", Framing(9600, parity="even"), DEVICE, [(0x63, True), (0x0D, False)]),  # MP-6: an 8E1 host
        (b"zc\r", Framing(9600, parity="even"), DEVICE, [(0x7A, False), (0x63, True), (0x0D, False)]),
        (b"c\r", Framing(9600, stop_bits=Fraction(2)), DEVICE, [(0x63, False), (0x0D, False)]),  # MP-6 item 3
    ],
)
def test_mp6_examples(data: bytes, sender: Framing, receiver: Framing, expected: list) -> None:
    assert decoded(garble(data, sender, receiver)) == expected


def test_8n1_bytes_at_an_8e1_receiver() -> None:
    """MP-6: the device's `31 0D` decodes at an 8E1 host as 00 (framing error) and C3 (parity error)."""
    chars = garble(b"1\r", DEVICE, Framing(9600, parity="even"))
    assert [(c.value, c.framing_error, c.parity_error) for c in chars] == [
        (0x31, True, False),
        (0xC3, False, True),
    ]


def test_same_framing_is_transparent() -> None:
    data = bytes(range(256))
    assert [c.value for c in garble(data, DEVICE, DEVICE)] == list(data)
    odd = Framing(2400, parity="odd", stop_bits=Fraction(3, 2))
    assert [c.value for c in garble(data, odd, odd)] == list(data)
    assert not any(c.parity_error or c.framing_error for c in garble(data, odd, odd))


def test_char_times_are_exact_stop_samples() -> None:
    """The receiver completes a character at its stop sample, 9.5 bit times after the start edge."""
    (char,) = garble(b"U", DEVICE, DEVICE)
    assert char.time == Fraction(19, 2 * 9600)
    assert DEVICE.char_time == Fraction(10, 9600)
    assert Framing(9600, parity="even", stop_bits=Fraction(2)).char_time == Fraction(12, 9600)


def test_framing_from_line_settings_fills_the_unseen() -> None:
    """MP-4: parity and data bits are invisible on a PTY (None): assumed to match."""
    host = HostLine(19200, None, None, 2, False, False)
    own = LineSettings(9600, 8, "odd", 1, False, False)
    assert Framing.of(host.filled(own)) == Framing(19200, 8, "odd", Fraction(2))
    assert Framing.of(LineSettings(4800, 8, "none", 1.5)) == Framing(4800, 8, "none", Fraction(3, 2))


def test_wire_only_decodes_what_is_final() -> None:
    """Samples at or after the horizon may still change: the wire waits and says what it needs."""
    wire = Wire(Framing(19200), DEVICE)
    wire.send(0x63, Fraction(0))
    assert wire.take(wire.line_free) == []  # the data sample at the frame's end needs the next level
    assert wire.needed is not None
    wire.send(0x0D, Fraction(0))  # back to back
    assert wire.take(wire.line_free) == []  # the stop sample lies after the second frame
    (char,) = wire.take(Fraction(1))
    assert char.value == 0x91
    assert wire.needed is None


def test_wire_snaps_nearly_back_to_back_bytes() -> None:
    """Float arrival times a hair after the previous byte's end count as back to back."""
    wire = Wire(Framing(19200), DEVICE)
    first = wire.send(0x63, Fraction(0))
    second = wire.send(0x0D, wire.line_free + Fraction(1, 10**12))
    assert second - first == Framing(19200).char_time
    assert [c.value for c in wire.take(Fraction(1))] == [0x91]


def test_idle_line_and_gaps() -> None:
    """Bytes with idle time between them decode on their own."""
    wire = Wire(DEVICE, DEVICE)
    wire.send(0x41, Fraction(0))
    wire.send(0x42, Fraction(1, 10))
    assert wire.level(Fraction(1, 20)) == 1
    assert [c.value for c in wire.take(Fraction(1))] == [0x41, 0x42]
