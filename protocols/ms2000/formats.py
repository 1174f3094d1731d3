"""MS2000 number formats of replies: F6, F3, integer and WHERE fixed point (MS-47, MS-48)."""

from __future__ import annotations

from decimal import ROUND_HALF_UP, Context, Decimal
from enum import Enum


class Fmt(Enum):
    F6 = "F6"
    F3 = "F3"
    I = "I"  # noqa: E741 - the specification's name
    W = "W"
    C = "C"


#: below this every integral double is an exact integer whose shortest text is its digits
_EXACT_INTEGERS = 2.0**53
#: enough digits for any finite double at 6 decimals
_DECIMALS = Context(prec=400, rounding=ROUND_HALF_UP)


def round_decimals(value: float, decimals: int) -> Decimal:
    """Half away from zero at `decimals` places, on the shortest decimal text of the value (so a
    value sent with at most that many decimals reads back exactly, MS-48)."""
    quantum = Decimal(1).scaleb(-decimals)
    return Decimal(repr(float(value))).quantize(quantum, context=_DECIMALS)


def fixed(value: float, decimals: int) -> str:
    """Fixed point, half away from zero, never `-0` (MS-47, MS-48)."""
    if decimals == 0 and -_EXACT_INTEGERS < value < _EXACT_INTEGERS and value == int(value):
        return str(int(value))  # the common WHERE case, exact without the decimal detour
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
