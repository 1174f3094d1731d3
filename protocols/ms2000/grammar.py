"""MS2000 command-line grammar: splitting a line into command and argument items (MS-19…MS-31).

Arguments are `L=v`, `L?`, `L+`, `L-`, bare `L` and bare numbers; prefixes may come before the key
letter, spaces may surround `=`, and a missing value reads as 0.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from protocols.ms2000.commands import SPLIT_CHARS, CommandSpec, lookup

#: MS-7: LF and TAB are whitespace; other control characters stay ordinary characters (MS-12)
_WHITESPACE = str.maketrans({"\n": " ", "\t": " "})
#: a number as the grammar reads it (also the value of a `NAME=number` reply item)
NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_SPACE_BEFORE_EQ = re.compile(r" +=")
_SPACE_AFTER_EQ = re.compile(r"= +(?=[-+.0-9])")


def normalize(text: str) -> str:
    """LF and TAB as spaces (MS-7)."""
    return text.translate(_WHITESPACE)


def is_blank(text: str) -> bool:
    return not normalize(text).strip(" ")


@dataclass(frozen=True)
class CommandLine:
    """A command line split into its command (None when unknown), the word as sent, and the raw text
    of its arguments."""

    spec: CommandSpec | None
    word: str
    args: str


def split_command(line: str) -> CommandLine:
    """Split a command line (without its CR). A line whose first non-blank character is `\\` is HALT
    whatever follows (MS-20); an unknown token starting with one of `\\ / ! ~ @` is split after that
    character (MS-19)."""
    text = normalize(line).lstrip(" ")
    if text.startswith("\\"):
        return CommandLine(lookup("\\"), "\\", text[1:])
    word, _, rest = text.partition(" ")
    spec = lookup(word)
    if spec is None and word and word[0] in SPLIT_CHARS:
        return CommandLine(lookup(word[0]), word[0], f"{word[1:]} {rest}")
    return CommandLine(spec, word, rest)


class Kind(Enum):
    SET = "="
    QUERY = "?"
    PLUS = "+"
    MINUS = "-"
    BARE = ""
    NUMBER = "#"
    MALFORMED = "!"


@dataclass(frozen=True)
class Item:
    """One argument item. `letter` is upper case (None for numbers and malformed tokens); `value` is
    the number of a set item (None when missing or not a number, MS-25) or of a bare number."""

    kind: Kind
    letter: str | None = None
    value: float | None = None
    text: str = ""


def _parse_number(text: str) -> float | None:
    if not NUMBER.fullmatch(text):
        return None
    value = float(text)
    return value if math.isfinite(value) else None


def _parse_prefix(text: str) -> float | None:
    """The number a value starts with, as C's `strtod` reads it: `50?` is 50, `1.5abc` 1.5, and a
    value that does not start with a number (`abc`) has none (MS-25)."""
    match = NUMBER.match(text)
    if match is None:
        return None
    value = float(match.group())
    return value if math.isfinite(value) else None


def _is_letter(ch: str) -> bool:
    return ("A" <= ch <= "Z") or ("a" <= ch <= "z")


def parse_items(args: str, numeric_prefix: bool = True) -> list[Item]:
    """Items of an argument text (MS-21…MS-26). The key of any item is the last letter before its
    suffix, so `VX=4.69`, `ACX=25` and `WTX=0` address X (MS-22). A set item's value is the number
    it starts with (`numeric_prefix`, the firmware's reading), or only a value that is a number as
    a whole (MS-25)."""
    text = normalize(args)
    if "=" in text:
        text = _SPACE_AFTER_EQ.sub("=", _SPACE_BEFORE_EQ.sub("=", text))
    items: list[Item] = []
    read_value = _parse_prefix if numeric_prefix else _parse_number
    for token in text.split(" "):
        if token:
            items.append(_parse_token(token, read_value))
    return items


def _parse_token(token: str, read_value: Callable[[str], float | None]) -> Item:
    if "=" in token:
        key, _, value = token.partition("=")
        if not key or not _is_letter(key[-1]):
            return Item(Kind.MALFORMED, text=token)
        return Item(Kind.SET, key[-1].upper(), read_value(value), token)
    number = _parse_number(token)
    if number is not None:
        return Item(Kind.NUMBER, None, number, token)
    suffix = token[-1]
    if suffix in "?+-" and len(token) >= 2 and _is_letter(token[-2]):
        kind = {"?": Kind.QUERY, "+": Kind.PLUS, "-": Kind.MINUS}[suffix]
        return Item(kind, token[-2].upper(), None, token)
    if _is_letter(suffix):
        return Item(Kind.BARE, suffix.upper(), None, token)
    return Item(Kind.MALFORMED, text=token)
