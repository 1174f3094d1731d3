"""What `stage-emu describe` shows of a resolved profile: one row per leaf (value, default, allowed
values, rule ID, meaning), and resolved values as plain data."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from emulator.profiles.schema import Derived, MapOf, Schema, Section, default_of, schema_fields, spec_of


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
    value: Schema, prefix: str = "", defaults: Mapping[str, Any] | None = None
) -> list[KnobRow]:
    """Flatten a resolved profile (or section) into rows (value, default, rule, meaning) in field
    order. Per-key tables of sections (MapOf(Section), e.g. axes) get one row per key and field;
    `defaults` carries a table's per-key default entries, which take precedence over the field
    defaults."""
    rows: list[KnobRow] = []
    defaults = defaults or {}
    for f in schema_fields(type(value)):
        spec = spec_of(f)
        current = getattr(value, f.name)
        path = f"{prefix}{f.name}"
        default = defaults.get(f.name, default_of(f))
        if isinstance(spec.type, Section):
            rows.extend(describe_rows(current, path + ".", default if isinstance(default, dict) else None))
            continue
        if isinstance(spec.type, MapOf) and isinstance(spec.type.value, Section) and current:
            table = default if isinstance(default, dict) else {}
            for key, entry in current.items():
                rows.extend(describe_rows(entry, f"{path}.{key}.", table.get(key)))
            continue
        shown = DerivedDefault(default.text) if isinstance(default, Derived) else default
        rows.append(KnobRow(path, plain(current), shown, spec.rule, spec.doc, spec.type.describe()))
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
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value
