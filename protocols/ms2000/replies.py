"""MS2000 replies as seen by a host: classifying one reply line (`parse_reply`)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum

from protocols.ms2000.grammar import NUMBER


class ReplyKind(Enum):
    ACK = "ack"
    ERROR = "error"
    VALUES = "values"
    BUSY = "busy"
    TEXT = "text"


@dataclass(frozen=True)
class ParsedReply:
    """A host's reading of one reply line. `values` keeps the `NAME=number` items (letter or
    `JS_FAST`...) in reply order; `numbers` keeps the items of an `:A` reply that are not all such
    items (the `A_list` values, or words such as `Version: USB-9.2k`); `text` is the line without
    terminator."""

    kind: ReplyKind
    text: str
    code: int | None = None
    values: tuple[tuple[str, str], ...] = ()
    numbers: tuple[str, ...] = ()

    def value(self, name: str) -> str:
        for key, value in self.values:
            if key == name:
                return value
        raise KeyError(f"{name!r} not in reply {self.text!r}")


_ERROR = re.compile(r":N-(\d+)")
_VALUE_ITEM = re.compile(rf"([A-Z][A-Z_]*)=({NUMBER.pattern})")


def parse_reply(line: bytes | str) -> ParsedReply:
    """Classify one reply line, the shapes of `format_items` (terminators, surrounding blanks and a
    leading LF left by CR-only readers are ignored). `:X=1 A` and `X=1 :A` count as values only
    when every item is `NAME=number`; otherwise, like any other line, they are text."""
    text = line.decode("latin-1") if isinstance(line, bytes) else line
    text = text.strip("\r\n")
    core = text.strip()
    error = _ERROR.fullmatch(core)
    if error:
        return ParsedReply(ReplyKind.ERROR, text, int(error.group(1)))
    if core in ("N", "B"):
        return ParsedReply(ReplyKind.BUSY, text)
    if core.startswith(":A"):
        tokens = core[2:].split()
        if not tokens:
            return ParsedReply(ReplyKind.ACK, text)
        values = _value_items(tokens)
        if values:
            return ParsedReply(ReplyKind.VALUES, text, values=values)
        return ParsedReply(ReplyKind.VALUES, text, numbers=tuple(tokens))
    if core.startswith(":") and core.endswith(" A"):
        values = _value_items(core[1:-2].split())
    elif core.endswith(":A"):
        values = _value_items(core[:-2].split())
    else:
        values = ()
    if values:
        return ParsedReply(ReplyKind.VALUES, text, values=values)
    return ParsedReply(ReplyKind.TEXT, text)


def _value_items(tokens: list[str]) -> tuple[tuple[str, str], ...]:
    """(name, number text) of each token, or () unless every token is `NAME=number`."""
    matches = [_VALUE_ITEM.fullmatch(token) for token in tokens]
    if not all(matches):
        return ()
    return tuple((m.group(1), m.group(2)) for m in matches if m)
