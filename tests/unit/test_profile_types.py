"""The annotations of the profile dataclasses tell the truth: what mypy is told a field holds is
what the validator puts there, for every bundled profile (so typed `knobs.x` reads can be trusted)."""

from __future__ import annotations

import types
from typing import Any, Union, get_args, get_origin, get_type_hints

import pytest

from emulator.profiles.profile import bundled_names, load_profile
from emulator.profiles.schema import Schema, schema_fields


def conforms(value: Any, hint: Any) -> bool:
    origin, args = get_origin(hint), get_args(hint)
    if hint is Any:
        return True
    if origin in (Union, types.UnionType):
        return any(conforms(value, arg) for arg in args)
    if origin is tuple:
        return isinstance(value, tuple) and all(conforms(item, args[0]) for item in value)
    if origin is dict:
        return isinstance(value, dict) and all(
            conforms(k, args[0]) and conforms(v, args[1]) for k, v in value.items()
        )
    if hint is float:  # an int is a float to mypy too
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, hint)


def mismatches(value: Schema, prefix: str = "") -> list[str]:
    hints = get_type_hints(type(value))
    found = []
    for f in schema_fields(type(value)):
        current, path = getattr(value, f.name), prefix + f.name
        if not conforms(current, hints[f.name]):
            found.append(f"{path}: {current!r} is not {hints[f.name]}")
        children = current.items() if isinstance(current, dict) else [("", current)]
        for key, child in children:
            if isinstance(child, Schema):
                found.extend(mismatches(child, f"{path}.{key}." if key else f"{path}."))
    return found


@pytest.mark.parametrize("name", bundled_names())
def test_bundled_profiles_match_their_annotations(name: str) -> None:
    assert mismatches(load_profile(name).config) == []


def test_a_mismatch_would_be_found() -> None:
    assert conforms(0.5, float) and conforms(2, float) and not conforms(True, int)
    assert conforms((1, 2), tuple[int, ...]) and not conforms((1, "x"), tuple[int, ...])
    assert conforms(None, float | None) and not conforms("x", float | None)
