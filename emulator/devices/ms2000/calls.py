"""What a command handler sees and returns, shared by the base controller and module plug-ins.

A handler takes a `Call` and returns a `Reply` (lines of bytes, without terminators), `SILENT`, or a
`Pending` for the few commands that reply only when their operation ends (MS-33). It raises
`CommandError(code)` for `:N-code`. `run_settings` implements the common validate-then-apply rules
of settings commands (MS-21, MS-25, MS-27…MS-31, MS-40).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

from protocols.ms2000 import CommandSpec, ErrorCode, Fmt, Item, Kind, Shape, format_items, format_value
from protocols.rounding import round_half_away

#: order of pseudo-axis parameters in replies (MS-29)
PSEUDO_ORDER = "XYZFTRM"
#: numbers beyond a 32-bit firmware variable are out of range [choice] (MS-26)
NUMBER_LIMIT = 2**31 - 1


class CommandError(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(f":N-{code}")
        self.code = int(code)


@dataclass(frozen=True)
class Reply:
    """Reply lines without terminators; no lines = no bytes at all."""

    lines: tuple[bytes, ...]

    @classmethod
    def text(cls, *lines: str) -> Reply:
        return cls(tuple(line.encode("latin-1") for line in lines))


SILENT = Reply(())


@dataclass
class Pending:
    """A command that replies when its operation ends (MS-33): `finish(t)` gives the reply at `due`,
    or, with no `due`, when the controller is told the operation ended (a save the host's store
    has settled). HALT cancels a `haltable` one, which then replies `:N-21`; lines behind it wait."""

    due: float | None
    finish: Callable[[float], Reply]
    cancel: Callable[[float], None] = field(default=lambda t: None)
    haltable: bool = True


@dataclass(frozen=True)
class Call:
    spec: CommandSpec
    items: tuple[Item, ...]
    args: str
    now: float

    @property
    def key(self) -> str:
        return self.spec.key

    def letters(self) -> list[str]:
        return [i.letter for i in self.items if i.letter is not None]


#: a command's handler, base or module
Handler = Callable[[Call], "Reply | Pending"]


@dataclass(frozen=True)
class Param:
    """One letter of a settings command. `check` returns the value to store or raises
    CommandError(4); `set` None makes the letter read-only (sets reply `:N-4`); `plus`/`minus` give
    `L+`/`L-` a meaning (otherwise they count as a missing value, i.e. 0)."""

    get: Callable[[], float | str]
    set: Callable[[float], None] | None = None
    check: Callable[[float], float] = lambda v: v
    fmt: Fmt = Fmt.I
    name: str | None = None
    plus: Callable[[], None] | None = None
    minus: Callable[[], None] | None = None


def number(item: Item) -> float:
    """The number of an item: a missing or non-numeric value is 0 (MS-25); beyond ±(2³¹−1)
    `:N-4`."""
    value = item.value if item.kind is Kind.SET and item.value is not None else 0.0
    if abs(value) > NUMBER_LIMIT:
        raise CommandError(ErrorCode.OUT_OF_RANGE)
    return value


def within(low: float, high: float, *, integer: bool = False) -> Callable[[float], float]:
    """A check accepting low…high (integers rounded half away from zero when `integer`)."""

    def check(value: float) -> float:
        if integer:
            value = float(round_half_away(value))
        if not low <= value <= high:
            raise CommandError(ErrorCode.OUT_OF_RANGE)
        return value

    return check


def whole(low: int, high: int) -> Callable[[float], float]:
    """A check accepting whole numbers low…high; a fraction is out of range, not rounded."""

    def check(value: float) -> float:
        if value != int(value) or not low <= value <= high:
            raise CommandError(ErrorCode.OUT_OF_RANGE)
        return value

    return check


def one_of(*allowed: float) -> Callable[[float], float]:
    def check(value: float) -> float:
        if value not in allowed:
            raise CommandError(ErrorCode.OUT_OF_RANGE)
        return value

    return check


class Lettered(Protocol):
    """What `axis_items` needs of an axis."""

    @property
    def letter(self) -> str: ...

    @property
    def index(self) -> int:
        """Hardware order."""


A = TypeVar("A", bound=Lettered)


def axis_items(call: Call, axes: Sequence[A], require: bool = True) -> list[tuple[A, Item]]:
    """Motor-axis items in hardware order, the last of a repeated letter winning (MS-27, MS-29);
    no items `:N-3`, a letter that is no motor axis `:N-2`, a malformed item `:N-6` (MS-30, MS-31)."""
    items = [i for i in call.items if i.kind is not Kind.NUMBER]
    if require and not items:
        raise CommandError(ErrorCode.MISSING_PARAMETERS)
    by_letter = {a.letter: a for a in axes}
    codes = []
    chosen: dict[A, Item] = {}
    for item in items:
        axis = by_letter.get(item.letter or "")
        if item.kind is Kind.MALFORMED:
            codes.append(ErrorCode.UNDEFINED)
        elif axis is None:
            codes.append(ErrorCode.BAD_AXIS)
        else:
            chosen[axis] = item
    first_error(codes)
    return sorted(chosen.items(), key=lambda pair: pair[0].index)


def first_error(codes: Iterable[int]) -> None:
    """Raise the lowest of the collected error codes, if any (MS-40)."""
    found = sorted(set(codes))
    if found:
        raise CommandError(found[0])


@dataclass(frozen=True)
class Rendered:
    """How the controller turns values into reply text: shape chosen by the command key after
    overrides, trailing-space knob, WHERE decimals."""

    shape: Shape
    trailing_space: bool
    where_decimals: int

    def items(self, pairs: Iterable[tuple[str, str]]) -> Reply:
        return Reply.text(format_items(self.shape, pairs, self.trailing_space))


def run_settings(
    call: Call,
    params: Mapping[str, Param],
    order: str | Iterable[str],
    render: Rendered,
    ack: Reply,
    require_items: bool = True,
) -> Reply:
    """Validate every item, apply all sets together, then reply the queried values in `order`."""
    items = [i for i in call.items if i.kind is not Kind.NUMBER]
    if require_items and not items:
        raise CommandError(ErrorCode.MISSING_PARAMETERS)
    codes: list[int] = []
    actions: dict[str, Callable[[], None]] = {}
    queries: list[str] = []
    for item in items:
        if item.kind is Kind.MALFORMED:
            codes.append(ErrorCode.UNDEFINED)
            continue
        param = params.get(item.letter or "")
        if param is None:
            codes.append(ErrorCode.BAD_AXIS)
            continue
        if item.kind is Kind.QUERY:
            queries.append(item.letter or "")
            continue
        action = _action(item, param)
        if isinstance(action, int):
            codes.append(action)
        else:
            actions[item.letter or ""] = action
    first_error(codes)
    for action in actions.values():
        action()
    if not queries:
        return ack
    ordered = [letter for letter in order if letter in queries]
    pairs = [(params[k].name or k, _show(params[k], render)) for k in ordered]
    return render.items(pairs)


def _action(item: Item, param: Param) -> Callable[[], None] | int:
    if item.kind is Kind.PLUS and param.plus is not None:
        return param.plus
    if item.kind is Kind.MINUS and param.minus is not None:
        return param.minus
    if param.set is None:
        return ErrorCode.OUT_OF_RANGE
    try:
        checked = param.check(number(item))
    except CommandError as exc:
        return exc.code
    setter = param.set
    return lambda: setter(checked)


def _show(param: Param, render: Rendered) -> str:
    value = param.get()
    if isinstance(value, str):
        return value
    return format_value(value, param.fmt, render.where_decimals)
