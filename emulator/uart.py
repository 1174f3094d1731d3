"""Bit-level model of an asynchronous serial line whose two ends are set up differently (MP-6).

One `Wire` is one direction of a line: a sender turns bytes into line levels at its own framing, a
receiver with another framing samples them. All arithmetic is exact (`fractions.Fraction`), so the
garbled bytes of a given exchange are always the same.

Sender: start bit 0, data bits LSB first, a parity bit if the sender uses parity, then its stop bits
at level 1. A byte starts at the later of its arrival and the end of the previous byte; otherwise the
line idles at 1.

Receiver: from the first 1->0 transition at or after the instant it is ready, it samples at the
centre of each of its bit times measured from that edge: start bit at 1/2 (a 1 there is a glitch:
the edge is ignored), data bits at 1 1/2 ..., then its parity bit if it uses one, then its first
stop bit, where a 0 is a framing error. It is ready again from the stop sample. A sample taken
exactly at a level change reads the new level. Only the first stop bit is ever checked.

The model is generic: endpoints are `Framing`s, built from anything with `baud`, `data_bits`,
`parity` and `stop_bits` attributes (e.g. `emulator.device.LineSettings`).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from emulator.device import LineSettings

HALF = Fraction(1, 2)
#: arrival times closer than this to the end of the previous byte count as back to back (the host's
#: float clock cannot express exact character boundaries)
SNAP = Fraction(1, 10**9)


@dataclass(frozen=True)
class Framing:
    """How one end frames characters."""

    baud: int
    data_bits: int = 8
    parity: str = "none"  # "none" | "even" | "odd"
    stop_bits: Fraction = Fraction(1)

    @classmethod
    def of(cls, settings: LineSettings) -> Framing:
        """From complete settings (a host's are first filled from the device's: `HostLine.filled`)."""
        baud, bits, parity, stop = settings.baud, settings.data_bits, settings.parity, settings.stop_bits
        if baud is None or bits is None or parity is None or stop is None:
            raise ValueError(f"incomplete line settings: {settings.describe()}")
        return cls(baud, bits, parity, Fraction(stop))

    @property
    def bit_time(self) -> Fraction:
        return Fraction(1, self.baud)

    @property
    def parity_bits(self) -> int:
        return 0 if self.parity == "none" else 1

    @property
    def char_time(self) -> Fraction:
        return (1 + self.data_bits + self.parity_bits + self.stop_bits) * self.bit_time

    def parity_of(self, value: int) -> int:
        ones = bin(value & ((1 << self.data_bits) - 1)).count("1")
        return ones % 2 if self.parity == "even" else 1 - ones % 2

    def levels(self, byte: int) -> tuple[int, ...]:
        """Levels of one character before its stop bits: start bit, data bits LSB first, parity."""
        bits = [0] + [(byte >> i) & 1 for i in range(self.data_bits)]
        if self.parity != "none":
            bits.append(self.parity_of(byte))
        return tuple(bits)


@dataclass(frozen=True)
class Char:
    """A character as the receiver decoded it, at the instant of its stop-bit sample."""

    time: Fraction
    value: int
    framing_error: bool = False
    parity_error: bool = False


@dataclass(frozen=True)
class _Frame:
    start: Fraction
    bit: Fraction
    levels: tuple[int, ...]
    end: Fraction

    def level(self, t: Fraction) -> int:
        index = (t - self.start) // self.bit
        return self.levels[index] if index < len(self.levels) else 1

    def falling_edges(self) -> list[Fraction]:
        edges = [self.start]  # always preceded by a stop bit or idle line
        for i in range(1, len(self.levels)):
            if self.levels[i - 1] == 1 and self.levels[i] == 0:
                edges.append(self.start + i * self.bit)
        return edges


class Wire:
    """One direction of a mismatched line: `send` bytes at the sender's framing, `take` what the
    receiver makes of them once every level it samples is known."""

    def __init__(self, sender: Framing, receiver: Framing, ready: Fraction = Fraction(0)) -> None:
        self.sender = sender
        self.receiver = receiver
        self._frames: list[_Frame] = []
        self._line_free = ready
        self._search_from = ready
        self._inclusive = True
        #: the instant whose level the receiver needs next (None: no edge to look at)
        self.needed: Fraction | None = None

    @property
    def line_free(self) -> Fraction:
        """End of the last character's stop bits."""
        return self._line_free

    def send(self, byte: int, at: Fraction) -> Fraction:
        """Put one byte on the line no earlier than `at`; returns its start instant."""
        start = at if at > self._line_free + SNAP else self._line_free
        bit = self.sender.bit_time
        levels = self.sender.levels(byte)
        end = start + (len(levels) + self.sender.stop_bits) * bit
        self._frames.append(_Frame(start, bit, levels, end))
        self._line_free = end
        if self.needed is None:
            self.needed = start
        return start

    def level(self, t: Fraction) -> int:
        for frame in self._frames:
            if frame.start <= t < frame.end:
                return frame.level(t)
        return 1

    def take(self, horizon: Fraction) -> list[Char]:
        """Characters whose every sample lies strictly before `horizon` (levels from `horizon` on
        may still change), in order."""
        chars = []
        receiver = self.receiver
        bit = receiver.bit_time
        stop_offset = (1 + receiver.data_bits + receiver.parity_bits) * bit + bit * HALF
        while True:
            edge = self._next_edge()
            if edge is None:
                self.needed = None
                break
            start_sample = edge + bit * HALF
            stop_sample = edge + stop_offset
            if start_sample >= horizon:
                self.needed = start_sample
                break
            if self.level(start_sample) == 1:  # glitch: ignore this edge
                self._search_from, self._inclusive = edge, False
                continue
            if stop_sample >= horizon:
                self.needed = stop_sample
                break
            chars.append(self._sample(edge, stop_sample))
            self._search_from, self._inclusive = stop_sample, True
            self._frames = [f for f in self._frames if f.end > stop_sample]
        return chars

    def _sample(self, edge: Fraction, stop_sample: Fraction) -> Char:
        receiver = self.receiver
        bit = receiver.bit_time
        value = 0
        for i in range(receiver.data_bits):
            value |= self.level(edge + (i + 1 + HALF) * bit) << i
        parity_error = False
        if receiver.parity != "none":
            parity = self.level(edge + (receiver.data_bits + 1 + HALF) * bit)
            parity_error = parity != receiver.parity_of(value)
        return Char(stop_sample, value, self.level(stop_sample) == 0, parity_error)

    def _next_edge(self) -> Fraction | None:
        after = self._search_from
        for frame in self._frames:
            if frame.end <= after:
                continue
            for edge in frame.falling_edges():
                if edge > after or (self._inclusive and edge == after):
                    return edge
        return None


def garble(data: bytes, sender: Framing, receiver: Framing) -> list[Char]:
    """What a receiver makes of `data` sent back to back from t = 0, the line idle afterwards."""
    wire = Wire(sender, receiver)
    for byte in data:
        wire.send(byte, Fraction(0))
    horizon = wire.line_free + 16 * max(sender.char_time, receiver.char_time)
    return wire.take(horizon)
