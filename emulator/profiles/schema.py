"""Typed profile fields: one declaration serves validation, defaults, typed results and `describe`.

A device family declares its profile as frozen dataclasses deriving from `Schema`. Every field is a
`setting(type, default, rule, doc)`: a dataclass field whose metadata holds its checker (type and
range), the behaviour rule it implements (e.g. `MP-6`) and a one-line meaning; a nested mapping is a
setting of type `Section(cls)`. The validator (`Section.check`), the defaults and `stage-emu describe`
read those fields, and mypy reads their annotations, so a misspelt `knobs.x` is a type error.

A field's dataclass default is its default as a profile would write it (a `Derived` one is computed
from the other fields): instances come from `Section.check`, which checks defaults like loaded values,
never from calling the class.

Numbers are always finite (`.nan` and `.inf` are refused); families give every duration, speed,
distance and factor a maximum too, so no value can overflow the model. Strings the device itself
prints are `Text(n, ascii=True)`: printable ASCII of at most n characters. Error messages are one
line and quote at most `SHOW_LIMIT` characters of a value; a section, list or mapping raises all
the problems of its items together (`SchemaErrors`), so that `validate` can list them.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import MISSING, dataclass, field
from functools import partial
from typing import Any, ClassVar, Generic, TypeVar

Path = tuple[str | int, ...]
SHOW_LIMIT = 60


def finite_number(value: Any) -> bool:
    """A number that device time and kinematics can compute with: not a bool, not NaN or infinite
    (JSON from a host or a state file, YAML from a profile, a command-line option)."""
    try:
        return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    except OverflowError:  # an integer too big for a float (JSON has no limit on digits)
        return False


class SchemaError(Exception):
    """A value that does not fit its field. `path` locates it inside the profile."""

    def __init__(self, path: Path, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


class SchemaErrors(SchemaError):
    """Every problem found in one value (a section, a list, a mapping), in the order checked; as a
    SchemaError it is the first, for callers that report one."""

    def __init__(self, errors: Sequence[SchemaError]) -> None:
        flat = tuple(one for error in errors for one in every_error(error))
        super().__init__(flat[0].path, flat[0].message)
        self.errors = flat


def every_error(error: SchemaError) -> tuple[SchemaError, ...]:
    """The problems `error` stands for: its own, or each of a SchemaErrors."""
    return error.errors if isinstance(error, SchemaErrors) else (error,)


def _checked(kind: Type, value: Any, path: Path, errors: list[SchemaError]) -> Any:
    """`kind.check(value, path)`, its SchemaError kept in `errors` (None then), so that a value
    reports all its problems."""
    try:
        return kind.check(value, path)
    except SchemaError as exc:
        errors.append(exc)
        return None


def path_text(path: Path) -> str:
    text = ""
    for part in path:
        if isinstance(part, str) and not (part.isprintable() and len(part) <= SHOW_LIMIT):
            part = _clip(repr(part))  # keep messages on one line
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def show_number(value: float) -> str:
    """A number for a message: short (`1e+06`, `0.001`) where that is exact, else every digit, so a
    value just past a bound never reads as the bound (`10000.0001`, not `10000`)."""
    try:
        short = f"{value:g}"
    except OverflowError:  # an integer past the float range (JSON allows any)
        return repr(value)
    return short if float(short) == value else repr(value)


def _show(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return _clip(repr(value) if isinstance(value, str) else str(value))


def _clip(text: str) -> str:
    return text if len(text) <= SHOW_LIMIT else text[: SHOW_LIMIT - 1] + "…"


@dataclass(frozen=True)
class Derived:
    """A default computed from the other values of the enclosing struct (after they are resolved)."""

    compute: Callable[[Mapping[str, Any]], Any]
    text: str


class Type:
    """Base of field types: normalise a loaded YAML value or raise SchemaError."""

    def check(self, value: Any, path: Path) -> Any:
        raise NotImplementedError

    def describe(self) -> str:
        raise NotImplementedError


@dataclass(frozen=True)
class Bool(Type):
    def check(self, value: Any, path: Path) -> bool:
        if not isinstance(value, bool):
            raise SchemaError(path, f"{_show(value)} is not a boolean (true or false)")
        return value

    def describe(self) -> str:
        return "bool"


@dataclass(frozen=True)
class Number(Type):
    integer: bool = False
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    choices: tuple[float, ...] | None = None

    def check(self, value: Any, path: Path) -> int | float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            kind = "an integer" if self.integer else "a number"
            raise SchemaError(path, f"{_show(value)} is not {kind}")
        if isinstance(value, float) and not math.isfinite(value):
            raise SchemaError(path, f"{_show(value)} is not a finite number")
        if self.integer and not (isinstance(value, int) or float(value).is_integer()):
            raise SchemaError(path, f"{_show(value)} is not an integer")
        if self.integer:
            value = int(value)
        if self.choices is not None and value not in self.choices:
            allowed = ", ".join(show_number(c) for c in self.choices)
            raise SchemaError(path, f"{_show(value)} is not one of {allowed}")
        low_bad = self.minimum is not None and (
            value <= self.minimum if self.exclusive_minimum else value < self.minimum
        )
        if low_bad or (self.maximum is not None and value > self.maximum):
            raise SchemaError(path, f"{_show(value)} is out of range ({self._range()})")
        return value

    def _range(self) -> str:
        above = ">" if self.exclusive_minimum else ">="
        low = "" if self.minimum is None else f"{above} {show_number(self.minimum)}"
        high = "" if self.maximum is None else f"<= {show_number(self.maximum)}"
        return ", ".join(part for part in (low, high) if part) or "any"

    def describe(self) -> str:
        kind = "int" if self.integer else "number"
        if self.choices is not None:
            return f"{kind} in {{{', '.join(show_number(c) for c in self.choices)}}}"
        bounds = self._range()
        return kind if bounds == "any" else f"{kind} {bounds}"


def Int(
    minimum: float | None = None, maximum: float | None = None, choices: Sequence[int] | None = None
) -> Number:
    return Number(True, minimum, maximum, False, tuple(choices) if choices is not None else None)


def Float(
    minimum: float | None = None, maximum: float | None = None, exclusive_minimum: bool = False
) -> Number:
    return Number(False, minimum, maximum, exclusive_minimum)


@dataclass(frozen=True)
class Str(Type):
    max_length: int | None = None
    pattern: str | None = None
    pattern_text: str = ""

    def check(self, value: Any, path: Path) -> str:
        if not isinstance(value, str):
            raise SchemaError(path, f"{_show(value)} is not a string")
        if self.max_length is not None and len(value) > self.max_length:
            raise SchemaError(path, f"{_show(value)} is longer than {self.max_length} characters")
        if self.pattern is not None and not re.fullmatch(self.pattern, value):
            raise SchemaError(
                path, f"{_show(value)} is not {self.pattern_text or 'of the form ' + self.pattern}"
            )
        return value

    def describe(self) -> str:
        notes = [note for note in (self.pattern_text, self._length()) if note]
        return f"string ({', '.join(notes)})" if notes else "string"

    def _length(self) -> str:
        return "" if self.max_length is None else f"at most {self.max_length} characters"


def Text(max_length: int, ascii: bool = False) -> Str:
    """One line of printable text of at most `max_length` characters; `ascii` for strings the
    device sends on its serial line or shows on its display."""
    if ascii:
        return Str(max_length, r"[ -~]*", "printable ASCII")
    return Str(max_length, r"[^\x00-\x1f\x7f-\x9f\u2028\u2029]*", "one line of printable text")


@dataclass(frozen=True)
class Choice(Type):
    values: tuple[Any, ...]

    def check(self, value: Any, path: Path) -> Any:
        # YAML reads `1.5` and `1` as numbers and `none` as a string; bools never match numbers.
        for allowed in self.values:
            if type(value) is type(allowed) and value == allowed:
                return value
            numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (allowed, value))
            if numeric and value == allowed:
                return allowed
        raise SchemaError(path, f"{_show(value)} is not one of {', '.join(_show(v) for v in self.values)}")

    def describe(self) -> str:
        return " | ".join(_show(v) for v in self.values)


@dataclass(frozen=True)
class Nullable(Type):
    inner: Type

    def check(self, value: Any, path: Path) -> Any:
        return None if value is None else self.inner.check(value, path)

    def describe(self) -> str:
        return f"{self.inner.describe()} or null"


@dataclass(frozen=True)
class ListOf(Type):
    item: Type
    length: int | None = None
    min_length: int = 0
    max_length: int | None = None
    unique: bool = False

    def check(self, value: Any, path: Path) -> tuple[Any, ...]:
        if not isinstance(value, list | tuple):
            raise SchemaError(path, f"{_show(value)} is not a list")
        if self.length is not None and len(value) != self.length:
            raise SchemaError(path, f"has {len(value)} items, expected exactly {self.length}")
        if len(value) < self.min_length:
            raise SchemaError(path, f"has {len(value)} items, expected at least {self.min_length}")
        if self.max_length is not None and len(value) > self.max_length:
            raise SchemaError(path, f"has {len(value)} items, expected at most {self.max_length}")
        errors: list[SchemaError] = []
        items = tuple(_checked(self.item, v, (*path, i), errors) for i, v in enumerate(value))
        if errors:
            raise SchemaErrors(errors)
        if self.unique and len(set(items)) != len(items):
            raise SchemaError(path, "contains duplicate items")
        return items

    def describe(self) -> str:
        size = f"{self.length} × " if self.length is not None else ""
        return f"list of {size}{self.item.describe()}"


@dataclass(frozen=True)
class MapOf(Type):
    """A mapping with free keys (e.g. per-axis tables keyed by letter); results in a plain dict."""

    key: Str
    value: Type

    def check(self, value: Any, path: Path) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise SchemaError(path, f"{_show(value)} is not a mapping")
        result = {}
        errors: list[SchemaError] = []
        for k, v in value.items():
            key = _checked(self.key, k, (*path, str(k)), errors)
            if key is not None:
                result[key] = _checked(self.value, v, (*path, key), errors)
        if errors:
            raise SchemaErrors(errors)
        return result

    def describe(self) -> str:
        return f"map of {self.key.describe()} to {self.value.describe()}"


class Schema:
    """Base of the dataclasses a profile is declared with."""

    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]  # set by @dataclass

    def validate(self, path: Path) -> None:
        """Cross-field checks, run once every field is resolved; raise SchemaError."""


S = TypeVar("S", bound=Schema)
#: metadata key of a field's `Spec`
SPEC = "schema"
#: class attribute of an `extend`ed schema: its field names in validation and `describe` order
ORDER = "_schema_order"


@dataclass(frozen=True)
class Spec:
    """What a field of a profile dataclass is besides its name and default."""

    type: Type
    rule: str = ""
    doc: str = ""


def setting(kind: Type, default: Any = None, rule: str = "", doc: str = "") -> Any:
    """A field of a profile dataclass: checker, default, the rule it implements and what it means.
    Typed `Any` because the default is a profile value (or `Derived`), not one of the field's type."""
    metadata = {SPEC: Spec(kind, rule, doc)}
    if isinstance(default, dict | list):  # dataclasses refuse mutable defaults
        return field(default_factory=partial(copy.deepcopy, default), metadata=metadata)
    return field(default=default, metadata=metadata)


def required(kind: Type, rule: str = "", doc: str = "") -> Any:
    """A field without a default (keyword-only, so that it may follow fields with one)."""
    return field(kw_only=True, metadata={SPEC: Spec(kind, rule, doc)})


def spec_of(f: dataclasses.Field[Any]) -> Spec:
    spec: Spec = f.metadata[SPEC]
    return spec


def default_of(f: dataclasses.Field[Any]) -> Any:
    """A field's declared default; `MISSING` when it is required."""
    if f.default_factory is not MISSING:
        return f.default_factory()
    return f.default


def schema_fields(cls: type[Schema]) -> list[dataclasses.Field[Any]]:
    """`cls`'s fields in validation and `describe` order: declaration order, with the fields
    `extend` added where it put them."""
    by_name = {f.name: f for f in dataclasses.fields(cls)}
    return [by_name[name] for name in getattr(cls, ORDER, by_name)]


@dataclass(frozen=True)
class Section(Type, Generic[S]):
    """A mapping with fixed keys, the fields of `cls`; results in a `cls`."""

    cls: type[S]

    def check(self, value: Any, path: Path) -> S:
        if value is None:
            value = {}
        if not isinstance(value, dict):
            raise SchemaError(path, f"{_show(value)} is not a mapping")
        fields = schema_fields(self.cls)
        known = {f.name for f in fields}
        allowed = ", ".join(sorted(known))
        errors = [
            SchemaError((*path, str(k)), f"unknown key; allowed here: {allowed}")
            for k in value
            if k not in known
        ]
        resolved: dict[str, Any] = {}
        derived: list[tuple[str, Type, Derived]] = []
        for f in fields:
            kind, default, at = spec_of(f).type, default_of(f), (*path, f.name)
            if f.name in value:
                resolved[f.name] = _checked(kind, value[f.name], at, errors)
            elif default is MISSING:
                errors.append(SchemaError(at, "is required"))
            elif isinstance(default, Derived):
                derived.append((f.name, kind, default))
            elif isinstance(kind, Section):
                resolved[f.name] = _checked(kind, default or {}, at, errors)
            else:
                resolved[f.name] = None if default is None else _checked(kind, default, at, errors)
        if errors:  # derived defaults and cross-field checks need every field resolved
            raise SchemaErrors(errors)
        for name, kind, rule in derived:
            computed = rule.compute(resolved)
            resolved[name] = None if computed is None else kind.check(computed, (*path, name))
        result = self.cls(**resolved)
        result.validate(path)
        return result

    def describe(self) -> str:
        return "mapping"


@dataclass(frozen=True)
class Field:
    """A field added to a schema at run time (by an MS2000 module, see `extend`)."""

    name: str
    type: Type
    default: Any = None
    rule: str = ""
    doc: str = ""


def extend(
    cls: type[S],
    extra: Sequence[Field],
    before: str | None = None,
    sections: Mapping[str, type[Schema]] | None = None,
) -> type[S]:
    """A subclass of `cls` with the fields `extra` (validated and described just before field
    `before`, else last) and with the nested sections named in `sections` given those classes."""
    own: list[tuple[str, Any, Any]] = [
        (f.name, Any, setting(f.type, f.default, f.rule, f.doc)) for f in extra
    ]
    inherited = {f.name: f for f in dataclasses.fields(cls)}
    for name, sub in (sections or {}).items():
        spec = spec_of(inherited[name])
        own.append((name, sub, setting(Section(sub), default_of(inherited[name]), spec.rule, spec.doc)))
    order = [f.name for f in schema_fields(cls)]
    at = order.index(before) if before is not None else len(order)
    order[at:at] = [f.name for f in extra]
    return dataclasses.make_dataclass(
        cls.__name__, own, bases=(cls,), namespace={ORDER: tuple(order)}, frozen=True
    )
