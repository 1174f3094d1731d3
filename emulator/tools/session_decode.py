"""Pairing a session's host requests with the device's replies (emulator/tools/session.py has the format).

`ExchangeDecoder` is fed the two directions as they were timed (`rx` host to device, `tx` device to
host) and yields `Exchange`s in request order. Requests are delimited by the protocol's own codec
(MS2000: a line up to CR; MP-285: `protocols.mp285.FrameParser`). Device bytes go to the oldest
request still waiting for its reply, so a host that sends several commands in one write still gets
each reply paired with its own command. A request stops waiting when:

- its reply is complete by the protocol's framing (MS2000 `\\r\\n`; MP-285 by the command's reply
  length, or an error code and CR);
- it expects no reply at all (MP-285 `r`, a bad frame that owes nothing);
- the host completed a later request in a later write while this one had heard nothing yet (no
  reply came: a knob that ignores the command, an interrupted move);
- a later request is complete, its reply already ends in CR and the next byte does not continue it
  (MS2000 with `VB X` bit 3 replies end in CR alone; a garbled MP-285 reply has no known length).

Device bytes while no request waits are an exchange of their own with no request (unsolicited
output: a TTL report, a crash signature, a reply after its request was given up).

The rule depends on the order of bytes and writes, never on timing, so a replay whose bytes come a
little earlier or later pairs them exactly as the recording did.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Protocol

from emulator.tools.trace import readable
from protocols.mp285 import FrameParser, reply_length
from protocols.mp285.errors import is_error_code
from protocols.mp285.parser import BadFrame, CtrlC, Frame, Item
from protocols.mp285.summary import describe_item, summarize_device
from protocols.mp285.vectors import VECTOR_LENGTH
from protocols.ms2000.summary import summarize_line

CR = 0x0D
LF = 0x0A


@dataclass(frozen=True)
class Request:
    """One host unit as the protocol's codec delimits it. `unit` is what the codec made of it
    (MP-285 parser item), for the framing's reply rules."""

    data: bytes
    summary: str
    expects_reply: bool = True
    unit: object = None


@dataclass
class Exchange:
    """A request (None: unsolicited device output) and the reply paired with it. `t` is when the
    request's last byte was written (for unsolicited output: its first byte arrived); `write` the
    index of that host write in the session; `pieces` the reply's bytes as (arrival time, bytes)."""

    request: Request | None
    t: float
    write: int = -1
    pieces: list[tuple[float, bytes]] = field(default_factory=list)
    #: a later request was completed in a later write than this one
    superseded: bool = False
    _reply: bytearray = field(default_factory=bytearray, repr=False)

    @property
    def reply(self) -> bytes:
        return bytes(self._reply)

    def add(self, t: float, byte: int) -> None:
        """One more reply byte, arrived at `t` (bytes of one arrival stay one piece)."""
        self._reply.append(byte)
        if self.pieces and self.pieces[-1][0] == t:
            self.pieces[-1] = (t, self.pieces[-1][1] + bytes((byte,)))
        else:
            self.pieces.append((t, bytes((byte,))))

    @property
    def first_latency(self) -> float | None:
        """Seconds from the request's end to the reply's first byte (None: no reply)."""
        return self.pieces[0][0] - self.t if self.pieces else None

    @property
    def latency(self) -> float | None:
        """Seconds from the request's end to the reply's last byte (None: no reply)."""
        return self.pieces[-1][0] - self.t if self.pieces else None

    def describe(self, family: str) -> str:
        """`W X Y [WHERE] -> ":A 0 0\\r\\n"`, `c -> position X=0 Y=0 Z=0 (µsteps)`, or
        `(unsolicited) -> ...`: the MP-285's binary replies by what they say alone."""
        head = "(unsolicited)" if self.request is None else self.request.summary
        return f"{head} -> {reply_text(family, self.reply, self.request, with_bytes=family != 'mp285')}"


def reply_text(family: str, reply: bytes, request: Request | None, *, with_bytes: bool = True) -> str:
    """A reply's bytes, and for the MP-285 what they say (replies carry no type, so the request
    helps), e.g. `"\\r" (CR (done))`."""
    if not reply:
        return "no reply"
    shown = readable(reply)
    if family != "mp285":
        return shown
    to = request.summary if request is not None else None
    gist = summarize_device(reply, to).removeprefix(f"reply to {to}: " if to else "reply: ")
    return f"{shown} ({gist})" if with_bytes else gist


class Framing(Protocol):
    """A family's codec rules: where host requests end and when a reply is complete."""

    def requests(self, data: bytes) -> list[Request]:
        """The requests `data` completes (fed in order; a partial one is kept for later bytes)."""
        ...

    def complete(self, request: Request, reply: bytes) -> bool: ...

    def ends_early(self, reply: bytes, next_byte: int) -> bool:
        """Whether a superseded request's reply so far is over, seeing the byte that follows it."""
        ...


class Ms2000Framing:
    """ASCII lines: a command up to CR; a reply up to CR LF (lines inside it end with bare CR)."""

    def __init__(self) -> None:
        self._line = bytearray()

    def requests(self, data: bytes) -> list[Request]:
        found = []
        for byte in data:
            self._line.append(byte)
            if byte == CR:
                line = bytes(self._line)
                self._line.clear()
                found.append(Request(line, summarize_line(line[:-1])))
        return found

    def complete(self, request: Request, reply: bytes) -> bool:
        return reply.endswith(b"\r\n")

    def ends_early(self, reply: bytes, next_byte: int) -> bool:
        return reply.endswith(b"\r") and next_byte != LF


class Mp285Framing:
    """Binary frames delimited by the device's own parser; fixed-length replies ending in CR."""

    def __init__(self) -> None:
        # a bad frame is discarded through the next CR whatever its length: no buffer limit here
        self._parser = FrameParser(input_buffer_size=1 << 30)
        self._unit = bytearray()

    def requests(self, data: bytes) -> list[Request]:
        found = []
        for byte in data:
            self._unit.append(byte)
            item = self._parser.feed_byte(byte)
            if item is not None:
                found.append(self._request(bytes(self._unit), item))
                self._unit.clear()
        return found

    @staticmethod
    def _request(data: bytes, item: Item) -> Request:
        silent = (isinstance(item, Frame) and reply_length(item.command) == 0) or (
            isinstance(item, BadFrame) and item.error is None
        )
        return Request(data, describe_item(item), not silent, item)

    def complete(self, request: Request, reply: bytes) -> bool:
        if not reply or reply[-1] != CR:
            return False
        if len(reply) == 2 and is_error_code(reply[0]):
            return True
        unit = request.unit
        if isinstance(unit, Frame):
            expected = reply_length(unit.command)
            if expected is None:  # `u`: the vector count, the vectors, CR
                return len(reply) == 2 + VECTOR_LENGTH * reply[0]
            return len(reply) == expected
        # ^C (`0D` idle, `3D` ... `0D` during a move), a stray CR or LF, a bad frame's error
        return not isinstance(unit, CtrlC) or len(reply) <= 2

    def ends_early(self, reply: bytes, next_byte: int) -> bool:
        return reply.endswith(b"\r")


def framing_for(family: str) -> Framing:
    if family == "mp285":
        return Mp285Framing()
    if family == "ms2000":
        return Ms2000Framing()
    raise ValueError(f"no framing for device family {family!r}")


class ExchangeDecoder:
    """Feed `rx` and `tx` in the order they happened; each call returns the exchanges it closed."""

    def __init__(self, family: str) -> None:
        self._framing = framing_for(family)
        self._waiting: deque[Exchange] = deque()
        #: unsolicited output still collecting (closed by the next request)
        self._loose: Exchange | None = None
        self._writes = 0

    def rx(self, t: float, data: bytes) -> list[Exchange]:
        write = self._writes
        self._writes += 1
        closed: list[Exchange] = []
        for request in self._framing.requests(data):
            if self._loose is not None:
                closed.append(self._loose)
                self._loose = None
            for earlier in self._waiting:
                if earlier.write < write:
                    earlier.superseded = True
            self._waiting.append(Exchange(request, t, write))
            closed += self._settle()
        return closed

    def tx(self, t: float, data: bytes) -> list[Exchange]:
        closed: list[Exchange] = []
        for byte in data:
            while self._waiting:
                head = self._waiting[0]
                if not (head.superseded and head.pieces and self._framing.ends_early(head.reply, byte)):
                    break
                closed.append(self._waiting.popleft())
                closed += self._settle()
            if not self._waiting:
                if self._loose is None:
                    self._loose = Exchange(None, t)
                self._loose.add(t, byte)
                continue
            head = self._waiting[0]
            head.add(t, byte)
            assert head.request is not None
            if self._framing.complete(head.request, head.reply):
                closed.append(self._waiting.popleft())
                closed += self._settle()
        return closed

    def finish(self) -> list[Exchange]:
        """The session ended: whatever is still open, in order."""
        closed = list(self._waiting)
        self._waiting.clear()
        if self._loose is not None:
            closed.append(self._loose)
            self._loose = None
        return closed

    def _settle(self) -> list[Exchange]:
        """Close the requests at the head that will get no reply."""
        closed = []
        while self._waiting:
            head = self._waiting[0]
            silent = head.request is not None and not head.request.expects_reply
            if not (silent or (head.superseded and not head.pieces)):
                break
            closed.append(self._waiting.popleft())
        return closed
