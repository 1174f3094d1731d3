"""ASI MS-2000 serial protocol: pure codec shared by the emulator and host-side clients.

No I/O, no clock and no emulator imports. It covers:
- the command table (long names, shortcuts, owning firmware module) and command-word matching;
- the argument grammar (`L=v`, `L?`, `L+`, `L-`, bare `L`, bare numbers; prefixes before the key
  letter, spaces around `=`, missing value = 0);
- how a host writes a command line (`format_command`, `command_line`);
- reply shapes and number formats, the error table, terminators and multi-line replies;
- reply classification for host programs (`parse_reply`), the INFO and BU X layouts;
- the low-level binary mode (control sequences, frames, 24-bit numbers);
- one-line traffic summaries.

Rule IDs (MS-n) refer to the project's MS-2000 behaviour specification; docs/ms2000.md explains them.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Context, Decimal
from enum import Enum, IntEnum

CR = b"\r"
CRLF = b"\r\n"
BASE = "base"

# ---- command table (MS-19, §2.3) -------------------------------------------------------------


@dataclass(frozen=True)
class CommandSpec:
    """One command word. `key` is the shortcut (or the long name when there is none) and is the name
    used everywhere else: reply-shape overrides, handler tables, summaries."""

    name: str
    short: str | None
    modules: tuple[str, ...] = (BASE,)
    aliases: tuple[str, ...] = ()

    @property
    def key(self) -> str:
        return self.short or self.name

    @property
    def is_base(self) -> bool:
        return BASE in self.modules

    def words(self) -> tuple[str, ...]:
        return tuple(w for w in (self.name, self.short, *self.aliases) if w)


def _c(name: str, short: str | None = None, *modules: str, aliases: tuple[str, ...] = ()) -> CommandSpec:
    return CommandSpec(name, short, modules or (BASE,), aliases)


AUTOFOCUS = "AUTOFOCUS"
CRISP = "CRISP"
TRACKING = "TRACKING"
ARRAY = "ARRAY MODULE"
SCAN = "SCAN MODULE"
RING_BUFFER = "RING BUFFER"
LED_DIMMER = "LED DIMMER"
DLED = "DLED"
INO_INT = "INO_INT"

COMMANDS: tuple[CommandSpec, ...] = (
    _c("AALIGN", "AA"),
    _c("ACCEL", "AC"),
    _c("AFCALIB", "AFC", AUTOFOCUS),
    _c("AFADJ", None, AUTOFOCUS),
    _c("AFINFO", None, AUTOFOCUS),
    _c("AFLIM", "AL", CRISP, AUTOFOCUS),
    _c("AFMOVE", "AM", AUTOFOCUS),
    _c("AFOCUS", "AF", AUTOFOCUS),
    _c("AHOME", "AH", ARRAY),
    _c("AIJ", None, ARRAY),
    _c("ARM", None, "SEQUENCER"),
    _c("ARRAY", "AR", ARRAY),
    _c("AZERO", "AZ"),
    _c("BACKLASH", "B"),
    _c("BCUSTOM", "BCA"),
    _c("BENABLE", "BE"),
    _c("BUILD", "BU"),
    _c("CDATE", "CD"),
    _c("CNTS", "C"),
    _c("CUSTOMA", "CCA"),
    _c("CUSTOMB", "CCB", "PLANAR CORRECTION"),
    _c("DACK", "D"),
    _c("DUMP", "DU"),
    _c("ENSYNC", "ES"),
    _c("EPOLARITY", "EP"),
    _c("ERROR", "E"),
    _c("EXTRA", "EX"),
    _c("HALT", "\\"),
    _c("HERE", "H"),
    _c("HOME", "!"),
    _c("INFO", "I"),
    _c("JOYSTICK", "J"),
    _c("JSSPD", "JS"),
    _c("KA"),
    _c("KD"),
    _c("KI"),
    _c("KP"),
    _c("KV"),
    _c("LCD"),
    _c("LED", None, LED_DIMMER, DLED),
    _c("LLADDR", "LL"),
    _c("LOAD", "LD", RING_BUFFER),
    _c("LOCK", "LK", CRISP, TRACKING),
    _c("LOCKRG", "LR", CRISP, TRACKING),
    _c("MAINTAIN", "MA"),
    _c("MOTCTRL", "MC", aliases=("MOTOCTRL",)),
    _c("MOVE", "M"),
    _c("MOVREL", "R", aliases=("MOVEREL",)),
    _c("MULTIMV", "MM", "MULTIAXIS MOVES"),
    _c("OS"),
    _c("PCROS", "PC"),
    _c("PEDAL", "PD", "PEDALS"),
    _c("RBMODE", "RM", RING_BUFFER),
    _c("RDADC", "RA"),
    _c("RDSBYTE", "RB"),
    _c("RDSTAT", "RS"),
    _c("RESET", "~"),
    _c("RTIME", "RT"),
    _c("RUNAWAY", "RU"),
    _c("SAVEPOS", "SP"),
    _c("SAVESET", "SS"),
    _c("SCAN", "SN", SCAN, ARRAY),
    _c("SCANR", "NR", SCAN),
    _c("SCANV", "NV", SCAN),
    _c("SECURE", None, "SOL_LK", "U_SERVO_LK"),
    _c("SETHOME", "HM"),
    _c("SETLOW", "SL"),
    _c("SETUP", "SU"),
    _c("SI", None, "SEARCH INDEX", "SEEK LIMITS"),
    _c("SPEED", "S"),
    _c("SPIN", "@"),
    _c("STATUS", "/"),
    _c("STOPBITS", "SB"),
    _c("TTL"),
    _c("UM"),
    _c("UNITS", "UN"),
    _c("UNLOCK", "UL", CRISP, TRACKING),
    _c("VB"),
    _c("VECTOR", "VE"),
    _c("VERSION", "V"),
    _c("WAIT", "WT"),
    _c("WHERE", "W"),
    _c("WHO", "N"),
    _c("WRDAC", None, "DAC OUT"),
    _c("Z2B"),
    _c("ZERO", "Z"),
    _c("ZS", None, INO_INT),
)

_BY_WORD: dict[str, CommandSpec] = {w.upper(): spec for spec in COMMANDS for w in spec.words()}
BY_KEY: dict[str, CommandSpec] = {spec.key: spec for spec in COMMANDS}
#: first characters that split off an unmatched command token (MS-19)
SPLIT_CHARS = "\\/!~@"


def lookup(word: str) -> CommandSpec | None:
    """The command a word names (long name, shortcut or alias; case-insensitive, MS-10)."""
    return _BY_WORD.get(word.upper())


# ---- line splitting and items (MS-19…MS-31) ---------------------------------------------------

#: MS-7: LF and TAB are whitespace; other control characters stay ordinary characters (MS-12)
_WHITESPACE = str.maketrans({"\n": " ", "\t": " "})
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
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
    if not _NUMBER.fullmatch(text):
        return None
    value = float(text)
    return value if math.isfinite(value) else None


def _is_letter(ch: str) -> bool:
    return ("A" <= ch <= "Z") or ("a" <= ch <= "z")


def parse_items(args: str) -> list[Item]:
    """Items of an argument text (MS-21…MS-26). The key of any item is the last letter before its
    suffix, so `VX=4.69`, `ACX=25` and `WTX=0` address X (MS-22)."""
    text = _SPACE_AFTER_EQ.sub("=", _SPACE_BEFORE_EQ.sub("=", normalize(args)))
    items: list[Item] = []
    for token in text.split(" "):
        if token:
            items.append(_parse_token(token))
    return items


def _parse_token(token: str) -> Item:
    if "=" in token:
        key, _, value = token.partition("=")
        if not key or not _is_letter(key[-1]):
            return Item(Kind.MALFORMED, text=token)
        return Item(Kind.SET, key[-1].upper(), _parse_number(value), token)
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


def format_command(word: str, items: Mapping[str, float | None] | Sequence[str] = ()) -> str:
    """A host command line without its CR: `format_command("M", {"X": 1000})` -> `M X=1000`; a
    mapping value None asks `L?`, a sequence sends its items verbatim (`["X+", "Y?"]`)."""
    parts = [word]
    if isinstance(items, Mapping):
        for letter, value in items.items():
            parts.append(f"{letter}?" if value is None else f"{letter}={host_number(value)}")
    else:
        parts.extend(items)
    return " ".join(parts)


def command_line(word: str, items: Mapping[str, float | None] | Sequence[str] = ()) -> bytes:
    """`format_command` encoded, with its CR: `command_line("M", {"X": 1000})` -> `b"M X=1000\\r"`."""
    return format_command(word, items).encode("ascii") + CR


def host_number(value: float) -> str:
    """A number as the controller's own examples send it: integers bare, others to 6 decimals."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.6f}"


# ---- number formats (MS-47, MS-48) ------------------------------------------------------------


class Fmt(Enum):
    F6 = "F6"
    F3 = "F3"
    I = "I"  # noqa: E741 - the specification's name
    W = "W"
    C = "C"


#: enough digits for any finite double at 6 decimals
_DECIMALS = Context(prec=400, rounding=ROUND_HALF_UP)


def round_decimals(value: float, decimals: int) -> Decimal:
    """Half away from zero at `decimals` places, on the shortest decimal text of the value (so a
    value sent with at most that many decimals reads back exactly, MS-48)."""
    quantum = Decimal(1).scaleb(-decimals)
    return Decimal(repr(float(value))).quantize(quantum, context=_DECIMALS)


def fixed(value: float, decimals: int) -> str:
    """Fixed point, half away from zero, never `-0` (MS-47, MS-48)."""
    rounded = round_decimals(value, decimals)
    if rounded == 0:
        rounded = abs(rounded)
    return f"{rounded:f}"


def f6(value: float) -> str:
    return fixed(value, 6)


def f3(value: float) -> str:
    return fixed(value, 3)


def integer(value: float) -> str:
    return fixed(value, 0)


def where(units: float, decimals: int = 0) -> str:
    """A WHERE-formatted position: `VB Z` decimals, no decimal point with 0 (MS-47)."""
    return fixed(units, decimals)


def format_value(value: float, fmt: Fmt, decimals: int = 0) -> str:
    if fmt is Fmt.F6:
        return f6(value)
    if fmt is Fmt.F3:
        return f3(value)
    if fmt is Fmt.W:
        return where(value, decimals)
    return integer(value)


# ---- reply shapes (§3) ------------------------------------------------------------------------


class Shape(Enum):
    ACK = "ack"
    A_AXIS = "A_axis"
    COLON_AXIS_A = "colon_axis_A"
    AXIS_COLON_A = "axis_colon_A"
    A_LIST = "A_list"
    BARE = "bare"
    BUSY_CHAR = "busy_char"


SHAPE_NAMES = tuple(s.value for s in Shape)
#: shapes that `reply_trailing_space` extends (MS-38)
TRAILING_SPACE_SHAPES = (Shape.A_AXIS, Shape.A_LIST, Shape.COLON_AXIS_A)

_A6 = (Shape.A_AXIS, Fmt.F6)
_AI = (Shape.A_AXIS, Fmt.I)
_A3 = (Shape.A_AXIS, Fmt.F3)
_AW = (Shape.A_AXIS, Fmt.W)
_CA6 = (Shape.COLON_AXIS_A, Fmt.F6)
_CAI = (Shape.COLON_AXIS_A, Fmt.I)
_LI = (Shape.A_LIST, Fmt.I)

#: query shape and number format per command key (MS-35); sets reply `ack`
QUERY_SHAPES: dict[str, tuple[Shape, Fmt]] = {
    **dict.fromkeys(("S", "PC", "VE", "D", "C", "UM", "RU", "ES", "RT", "OS"), _A6),
    **dict.fromkeys(
        ("KP", "KI", "KD", "KV", "KA", "AA", "EP", "MA", "TTL", "LL", "VB", "SB", "Z2B", "BE", "BCA"), _AI
    ),
    **dict.fromkeys(("CCA", "SP", "J", "SI", "ZS", "AZ", "RM"), _AI),
    **dict.fromkeys(("SL", "SU", "HM"), _A3),
    **dict.fromkeys(("B", "E"), _CA6),
    **dict.fromkeys(("AC", "WT"), _CAI),
    "JS": _AI,
    **dict.fromkeys(("LED", "SECURE"), (Shape.AXIS_COLON_A, Fmt.I)),
    "WRDAC": (Shape.AXIS_COLON_A, Fmt.F6),
    "W": (Shape.A_LIST, Fmt.W),
    **dict.fromkeys(("RS", "RA", "MC"), _LI),
    "LD": _AW,
    "/": (Shape.BUSY_CHAR, Fmt.C),
}


def query_shape(key: str, overrides: Mapping[str, str] | None = None) -> Shape:
    """The shape of a command's query reply, after `reply_shape_overrides` (MS-36…MS-38)."""
    if overrides and key in overrides:
        return Shape(overrides[key])
    return QUERY_SHAPES.get(key, _AI)[0]


def format_items(shape: Shape, items: Iterable[tuple[str, str]], trailing_space: bool = False) -> str:
    """The reply body (without terminator) for (name, formatted value) items in reply order."""
    pairs = list(items)
    if shape is Shape.ACK:
        body = ":A"
    elif shape is Shape.A_AXIS:
        body = ":A" + "".join(f" {n}={v}" for n, v in pairs)
    elif shape is Shape.COLON_AXIS_A:
        body = ":" + " ".join(f"{n}={v}" for n, v in pairs) + " A"
    elif shape is Shape.AXIS_COLON_A:
        body = " ".join(f"{n}={v}" for n, v in pairs) + " :A"
    elif shape is Shape.A_LIST:
        body = ":A" + "".join(f" {v}" for _, v in pairs)
    elif shape is Shape.BUSY_CHAR:
        body = pairs[0][1] if pairs else "N"
    else:
        body = " ".join(v for _, v in pairs)
    if trailing_space and shape in TRAILING_SPACE_SHAPES:
        body += " "
    return body


def ack(trailing_space: bool = False) -> str:
    """`:A`, or `:A ` with knob `ack_trailing_space` (MS-17)."""
    return ":A " if trailing_space else ":A"


def terminator(cr_only: bool) -> bytes:
    """CR LF, or CR alone with `VB X` bit 3 (MS-14, MS-16)."""
    return CR if cr_only else CRLF


def frame(lines: Sequence[bytes], cr_only: bool = False) -> bytes:
    """A complete reply: lines separated by bare CR, then the terminator (MS-15)."""
    return CR.join(lines) + terminator(cr_only)


# ---- errors (§4) ------------------------------------------------------------------------------


class ErrorCode(IntEnum):
    UNKNOWN_COMMAND = 1
    BAD_AXIS = 2
    MISSING_PARAMETERS = 3
    OUT_OF_RANGE = 4
    FAILED = 5
    UNDEFINED = 6
    HALTED = 21


#: the meaning of each error code (MS-39)
ERROR_TEXT: dict[int, str] = {
    ErrorCode.UNKNOWN_COMMAND: "unknown command",
    ErrorCode.BAD_AXIS: "unrecognised axis parameter",
    ErrorCode.MISSING_PARAMETERS: "missing parameters",
    ErrorCode.OUT_OF_RANGE: "parameter out of range",
    ErrorCode.FAILED: "operation failed",
    ErrorCode.UNDEFINED: "undefined error",
    ErrorCode.HALTED: "serial command halted by HALT",
}


def error_text(code: int) -> str:
    """The meaning of `:N-<code>`; `error` for a code outside the table."""
    return ERROR_TEXT.get(code, "error")


def error_reply(code: int) -> str:
    return f":N-{int(code)}"


# ---- replies as seen by a host ----------------------------------------------------------------


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
_VALUE_ITEM = re.compile(rf"([A-Z][A-Z_]*)=({_NUMBER.pattern})")


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


def split_lines(block: bytes) -> list[bytes]:
    """The lines of a multi-line reply (MS-15), terminator removed."""
    if block.endswith(CRLF):
        block = block[:-2]
    elif block.endswith(CR):
        block = block[:-1]
    return block.split(CR) if block else [b""]


# ---- text reports: INFO (MS-106) and BU X (MS-102) -------------------------------------------

#: each INFO row holds two items, the left one padded to this many characters
INFO_LEFT_WIDTH = 33
#: the BU X lines naming the motor axes (in hardware order, MS-29) and the command letters
BU_MOTOR_AXES = "Motor Axes:"
BU_CMDS = "CMDs:"


def parse_info(report: str) -> dict[str, str]:
    """An INFO report (rows separated by CR) as {label: value with units}."""
    result: dict[str, str] = {}
    for row in report.split("\r"):
        for item in (row[:INFO_LEFT_WIDTH], row[INFO_LEFT_WIDTH:]):
            label, sep, value = item.partition(":")
            if sep and label.strip():
                result[label.strip()] = value.strip()
    return result


# ---- low-level binary mode (§8) ---------------------------------------------------------------

CONTROL = 0xFF
LL_TERMINATOR = 0x3A
INT24_MAX = (1 << 23) - 1


class LLCommand(IntEnum):
    BUSY = ord("?")
    POSITION = ord("a")
    POSITION_STATUS = ord("l")
    STATUS = ord("~")
    START_MOTOR = ord("G")
    JOYSTICK_ON = ord("J")
    JOYSTICK_OFF = ord("K")
    MOVE_TO = ord("T")
    STEP_UP = ord("+")
    STEP_DOWN = ord("-")
    WRITE_INCREMENT = ord("D")
    READ_INCREMENT = ord("d")


LL_WRITES = frozenset({LLCommand.MOVE_TO, LLCommand.WRITE_INCREMENT})
#: reply length of each read command (MS-121)
LL_REPLY_LENGTH = {
    LLCommand.BUSY: 1,
    LLCommand.POSITION: 3,
    LLCommand.POSITION_STATUS: 4,
    LLCommand.STATUS: 1,
    LLCommand.READ_INCREMENT: 3,
}
#: the n a host sends with each read: the reply length, except `l` (3 position bytes, the status
#: byte comes on top) and `?` (0), as in ASI's examples (MS-120)
LL_READ_N = {
    LLCommand.BUSY: 0,
    LLCommand.POSITION: 3,
    LLCommand.POSITION_STATUS: 3,
    LLCommand.STATUS: 1,
    LLCommand.READ_INCREMENT: 3,
}


def encode_int24(value: int) -> bytes:
    """24-bit two's complement, least significant byte first; values outside ±8388607 wrap (MS-120)."""
    return (int(value) & 0xFFFFFF).to_bytes(3, "little")


def decode_int24(data: bytes) -> int:
    value = int.from_bytes(data[:3], "little")
    return value - (1 << 24) if value & 0x800000 else value


def encode_ll_frame(axis_id: int, command: int, value: int | None = None, n: int | None = None) -> bytes:
    """A host frame: axis id, command, n, data, `:`. Write commands carry `value` as 3 data bytes;
    reads send their reply length as n unless `n` says otherwise (MS-120)."""
    if value is not None:
        data = encode_int24(value)
        return bytes([axis_id, command, len(data)]) + data + b":"
    length = LL_READ_N.get(LLCommand(command), 0) if n is None else n
    return bytes([axis_id, command, length]) + b":"


@dataclass(frozen=True)
class LLFrame:
    """A decoded host frame. `known` is False for frames the controller consumes and ignores."""

    axis_id: int
    command: int
    data: bytes = b""
    known: bool = True


class LLFrameDecoder:
    """Incremental decoder of host frames (MS-120, MS-123). `feed(byte)` returns a frame when one
    completes. `axis_ids` are the ids in use; frames for other ids are consumed up to `:` and
    returned with `known=False`."""

    def __init__(self, axis_ids: Iterable[int] = ()) -> None:
        self.axis_ids = set(axis_ids)
        self.reset()

    def reset(self) -> None:
        self._state = "axis"
        self._axis = 0
        self._command = 0
        self._need = 0
        self._data = bytearray()
        self._ignore = False

    def feed(self, byte: int) -> LLFrame | None:
        state = self._state
        if state == "axis":
            self._axis = byte
            self._ignore = byte not in self.axis_ids
            self._state = "skip" if self._ignore else "command"
            return None
        if state == "command":
            self._command = byte
            known = byte in LLCommand._value2member_map_
            if not known:
                self._ignore = True
                self._state = "skip"
            else:
                self._state = "count"
            return None
        if state == "count":
            if self._command in LL_WRITES:
                self._need = byte
                self._data.clear()
                self._state = "data" if byte else "end"
                return None
            # reads and zero-data commands: n (if any) and stray bytes up to `:` are ignored
            if byte == LL_TERMINATOR:
                return self._finish()
            self._state = "skip"
            return None
        if state == "data":
            self._data.append(byte)
            if len(self._data) >= self._need:
                self._state = "end"
            return None
        if state == "end":
            if byte == LL_TERMINATOR:
                if len(self._data) != 3:
                    self._ignore = True
                return self._finish()
            self._ignore = True
            self._state = "skip"
            return None
        # skip: consume up to the next terminator
        if byte == LL_TERMINATOR:
            return self._finish()
        return None

    def _finish(self) -> LLFrame:
        frame_ = LLFrame(self._axis, self._command, bytes(self._data), not self._ignore)
        self.reset()
        return frame_


# ---- traffic summaries --------------------------------------------------------------------------


def shown(data: bytes) -> str:
    """Bytes for the traffic log: printable text with escapes (`:A 0 0 \\r\\n`), else hex."""
    text = data.decode("latin-1")
    if not all(32 <= ord(ch) < 127 or ch in "\r\n\t" for ch in text):
        return f"binary {data.hex(' ')}"
    return text.replace("\r", "\\r").replace("\n", "\\n").replace("\t", "\\t")


def summarize_line(line: bytes) -> str:
    """A command line (without its CR) with its command spelled out: `M X=1000 [MOVE]`."""
    text = line.decode("latin-1")
    if is_blank(text):
        return "blank line"
    spec = split_command(text).spec
    return f"{shown(line)} [{spec.name if spec else '?'}]"
