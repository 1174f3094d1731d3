"""Typed profile fields: one declaration serves validation, defaults, frozen results and `describe`.

A device family declares its profile as a `Struct` of fields. Each field knows its type and range,
its default, the behaviour rule it implements (e.g. `MP-6`) and a one-line meaning, so the validator,
the frozen dataclasses and `stage-emu describe` all come from the same list.

Numbers are always finite (`.nan` and `.inf` are refused); families give every duration, speed,
distance and factor a maximum too, so no value can overflow the model. Strings the device itself
prints are `Text(n, ascii=True)`: printable ASCII of at most n characters. Error messages are one
line and quote at most `SHOW_LIMIT` characters of a value.
"""

from __future__ import annotations

import dataclasses
import keyword
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

Path = tuple[str | int, ...]
SHOW_LIMIT = 60


class SchemaError(Exception):
    """A value that does not fit its field. `path` locates it inside the profile."""

    def __init__(self, path: Path, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


def path_text(path: Path) -> str:
    text = ""
    for part in path:
        if isinstance(part, str) and not (part.isprintable() and len(part) <= SHOW_LIMIT):
            part = _clip(repr(part))  # keep messages on one line
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


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
            allowed = ", ".join(f"{c:g}" for c in self.choices)
            raise SchemaError(path, f"{_show(value)} is not one of {allowed}")
        low_bad = self.minimum is not None and (
            value <= self.minimum if self.exclusive_minimum else value < self.minimum
        )
        if low_bad or (self.maximum is not None and value > self.maximum):
            raise SchemaError(path, f"{_show(value)} is out of range ({self._range()})")
        return value

    def _range(self) -> str:
        low = "" if self.minimum is None else f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}"
        high = "" if self.maximum is None else f"<= {self.maximum:g}"
        return ", ".join(part for part in (low, high) if part) or "any"

    def describe(self) -> str:
        kind = "int" if self.integer else "number"
        if self.choices is not None:
            return f"{kind} in {{{', '.join(f'{c:g}' for c in self.choices)}}}"
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
        items = tuple(self.item.check(v, (*path, i)) for i, v in enumerate(value))
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
        for k, v in value.items():
            key = self.key.check(k, (*path, str(k)))
            result[key] = self.value.check(v, (*path, key))
        return result

    def describe(self) -> str:
        return f"map of {self.key.describe()} to {self.value.describe()}"


@dataclass(frozen=True)
class Field:
    """One key of a struct: its type, default, the rule it implements and what it means."""

    name: str
    type: Type
    default: Any = None
    rule: str = ""
    doc: str = ""
    required: bool = False


@dataclass(frozen=True)
class Struct(Type):
    """A mapping with fixed keys; results in a frozen dataclass named `name`."""

    name: str
    fields: tuple[Field, ...]
    #: cross-field check run after the defaults are resolved; raises SchemaError
    validate: Callable[[Mapping[str, Any], Path], None] | None = None
    _cls: list[type] = field(default_factory=list, compare=False, repr=False)

    def field_named(self, name: str) -> Field | None:
        return next((f for f in self.fields if f.name == name), None)

    def dataclass(self) -> type:
        if not self._cls:
            names = [(_attr(f.name), Any) for f in self.fields]
            self._cls.append(dataclasses.make_dataclass(self.name, names, frozen=True))
        return self._cls[0]

    def check(self, value: Any, path: Path) -> Any:
        if value is None:
            value = {}
        if not isinstance(value, dict):
            raise SchemaError(path, f"{_show(value)} is not a mapping")
        known = {f.name for f in self.fields}
        for key in value:
            if key not in known:
                raise SchemaError((*path, str(key)), f"unknown key; allowed here: {', '.join(sorted(known))}")
        resolved: dict[str, Any] = {}
        derived: list[Field] = []
        for f in self.fields:
            if f.name in value:
                resolved[f.name] = f.type.check(value[f.name], (*path, f.name))
            elif f.required:
                raise SchemaError((*path, f.name), "is required")
            elif isinstance(f.default, Derived):
                derived.append(f)
            elif isinstance(f.type, Struct):
                resolved[f.name] = f.type.check(f.default or {}, (*path, f.name))
            else:
                resolved[f.name] = f.type.check(f.default, (*path, f.name)) if f.default is not None else None
        for f in derived:
            default = f.default.compute(resolved)
            resolved[f.name] = None if default is None else f.type.check(default, (*path, f.name))
        if self.validate is not None:
            self.validate(resolved, path)
        return self.dataclass()(**{_attr(k): v for k, v in resolved.items()})

    def describe(self) -> str:
        return "mapping"


def _attr(name: str) -> str:
    return f"{name}_" if keyword.iskeyword(name) else name


@dataclass(frozen=True)
class KnobRow:
    """One leaf of a resolved profile, for `stage-emu describe`."""

    path: str
    value: Any
    default: Any
    rule: str
    doc: str
    type: str


def describe_rows(
    struct: Struct, value: Any, prefix: str = "", defaults: Mapping[str, Any] | None = None
) -> list[KnobRow]:
    """Flatten a resolved struct into rows (value, default, rule, meaning) in declaration order.
    Per-key tables of structs (MapOf(Struct), e.g. axes) get one row per key and field; `defaults`
    carries a table's per-key default entries, which take precedence over the field defaults."""
    rows: list[KnobRow] = []
    defaults = defaults or {}
    for f in struct.fields:
        current = getattr(value, _attr(f.name))
        path = f"{prefix}{f.name}"
        default = defaults.get(f.name, f.default)
        if isinstance(f.type, Struct):
            nested = default if isinstance(default, dict) else None
            rows.extend(describe_rows(f.type, current, path + ".", nested))
            continue
        if isinstance(f.type, MapOf) and isinstance(f.type.value, Struct) and current:
            table = default if isinstance(default, dict) else {}
            for key, entry in current.items():
                rows.extend(describe_rows(f.type.value, entry, f"{path}.{key}.", table.get(key)))
            continue
        shown = DerivedDefault(default.text) if isinstance(default, Derived) else default
        rows.append(KnobRow(path, plain(current), shown, f.rule, f.doc, f.type.describe()))
    return rows


@dataclass(frozen=True)
class DerivedDefault:
    """The default of a field computed from other values: only its description is known."""

    text: str

    def __str__(self) -> str:
        return f"({self.text})"


def plain(value: Any) -> Any:
    """A resolved value as plain data (dataclasses to dicts, tuples to lists)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name.rstrip("_"): plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value
