"""MS2000 reply shapes (§3): the query shape of each command and the reply body of each shape."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import Enum

from protocols.ms2000.formats import Fmt


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
