"""MS2000 reply shapes (§3): the query shape of each command and the reply body of each shape."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import Enum


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

#: query reply shape per command key (MS-35); a key not listed answers `:A X=…`. Setting commands
#: reply `ack`. How each value is written is the command's own (its parameters' number format).
QUERY_SHAPES: dict[str, Shape] = {
    **dict.fromkeys(("B", "E", "AC", "WT"), Shape.COLON_AXIS_A),
    **dict.fromkeys(("LED", "SECURE", "WRDAC"), Shape.AXIS_COLON_A),
    **dict.fromkeys(("W", "RS", "RA", "MC"), Shape.A_LIST),
    "/": Shape.BUSY_CHAR,
}


def query_shape(key: str, overrides: Mapping[str, str] | None = None) -> Shape:
    """The shape of a command's query reply, after `reply_shape_overrides` (MS-36…MS-38)."""
    if overrides and key in overrides:
        return Shape(overrides[key])
    return QUERY_SHAPES.get(key, Shape.A_AXIS)


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
