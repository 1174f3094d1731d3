"""Finite ranges and bounded strings of the device profiles (issue #9), extends rules and limits."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from emulator.profiles.profile import MAX_CHAIN, ProfileError, load_profile
from emulator.profiles.registry import family
from emulator.profiles.schema import (
    ListOf,
    MapOf,
    Nullable,
    Number,
    Schema,
    Section,
    Str,
    Text,
    Type,
    schema_fields,
    spec_of,
)

#: numbers bounded by a cross-field check instead of their own range (MP-30: positions in 32 bits)
CHECKED_ELSEWHERE = {"stage.origin_usteps_from_bot"}


def numbers(schema: type[Schema], prefix: str = "") -> dict[str, Number]:
    """Every number field of a schema, by dotted path."""
    found: dict[str, Number] = {}
    for f in schema_fields(schema):
        kind: Type = spec_of(f).type
        while isinstance(kind, Nullable | ListOf | MapOf):
            kind = (
                kind.inner
                if isinstance(kind, Nullable)
                else kind.item
                if isinstance(kind, ListOf)
                else kind.value
            )
        if isinstance(kind, Section):
            found.update(numbers(kind.cls, f"{prefix}{f.name}."))
        elif isinstance(kind, Number):
            found[f"{prefix}{f.name}"] = kind
    return found


@pytest.mark.parametrize("name", ["mp285", "ms2000"])
def test_every_number_has_a_finite_range(name: str) -> None:
    fam = family(name)
    assert fam is not None
    unbounded = [
        path
        for path, kind in numbers(fam.schema).items()
        if kind.choices is None and (kind.minimum is None or kind.maximum is None)
    ]
    assert set(unbounded) <= CHECKED_ELSEWHERE


def error_of(name: str, overrides: dict) -> str:
    with pytest.raises(ProfileError) as info:
        load_profile(name, overrides)
    return str(info.value)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"axes": {"X": {"pitch_mm": 1e300}}}, "axes.X.pitch_mm: 1e+300 is out of range (> 0, <= 100)"),
        (
            {"axes": {"X": {"soft_lower_mm": float("-inf")}}},
            "axes.X.soft_lower_mm: -inf is not a finite number",
        ),
        (
            {"axes": {"X": {"unit_multiplier": float("nan")}}},
            "axes.X.unit_multiplier: nan is not a finite number",
        ),
        ({"axes": {"X": {"travel_mm": [-1e6, 60]}}}, "axes.X.travel_mm[0]: -1000000.0 is out of range"),
        (
            {"axes": {"X": {"counts_per_mm": 1e7}}},
            "axes.X.counts_per_mm: 10000000.0 is out of range (> 0, <= 1e+06)",
        ),
        ({"axes": {"X": {"speed_mm_s": 1e4}}}, "axes.X.speed_mm_s: 10000.0 is out of range (> 0, <= 1000)"),
        ({"knobs": {"landing_ms": 1e300}}, "knobs.landing_ms: 1e+300 is out of range (>= 0, <= 3.6e+06)"),
        ({"wheel_um_per_count": float("inf")}, "wheel_um_per_count: inf is not a finite number"),
        ({"version": "USB-9.2k\r"}, "version: 'USB-9.2k\\r' is not printable ASCII"),
        ({"version": "USB-9.2k\u00e9"}, "version: 'USB-9.2ké' is not printable ASCII"),
        ({"version": "USB-" + "9" * 17}, "is longer than 20 characters"),
        ({"who": "W" * 33}, "who: 'WWWWW"),
        ({"build_name": "STD\nXYZ"}, "build_name: 'STD\\nXYZ' is not printable ASCII"),
        ({"cdate": "Mar 14 2016:17:32:08 "}, "cdate: 'Mar 14 2016:17:32:08 ' is longer than 20 characters"),
        ({"device_id": "x" * 65}, "device_id: "),
    ],
)
def test_ms2000_ranges_and_strings(overrides: dict, message: str) -> None:
    """MS-54 ... MS-71 ranges; MS-99, MS-100, MS-101, MS-105, MS-111 identity strings."""
    assert message in error_of("ms2000", overrides)


def test_ms2000_strings_at_their_bounds_load() -> None:
    config = load_profile("ms2000", {"version": "USB-" + "9" * 16, "who": "W" * 32}).config
    assert (len(config.version), len(config.who)) == (20, 32)


def test_describe_shows_string_bounds_and_ranges() -> None:
    types = {row.path: row.type for row in load_profile("ms2000").describe()}
    assert types["version"] == "string (printable ASCII, at most 20 characters)"
    assert types["axes.X.pitch_mm"] == "number > 0, <= 100"
    assert types["axes.X.travel_mm"] == "list of 2 × number >= -10000, <= 10000"
    assert Text(5).describe() == "string (one line of printable text, at most 5 characters)"
    assert Str().describe() == "string"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_extends_chain_up_to_the_limit_loads(tmp_path: Path) -> None:
    write(tmp_path, f"c{MAX_CHAIN - 1}.yaml", "spec: 1\ndevice: mp285\n")
    for i in range(MAX_CHAIN - 1):
        write(tmp_path, f"c{i}.yml" if i == 0 else f"c{i}.yaml", f"spec: 1\nextends: c{i + 1}.yaml\n")
    assert len(load_profile(str(tmp_path / "c0.yml")).chain) == MAX_CHAIN
    write(tmp_path, "c-1.yaml", "spec: 1\nextends: c0.yml\n")
    assert f"c{MAX_CHAIN - 2}.yaml:2: extends: extends chain longer than 16 profiles" in error_of(
        str(tmp_path / "c-1.yaml"), {}
    )


def test_other_family_blames_the_child(tmp_path: Path) -> None:
    child = write(tmp_path, "stage.yaml", "spec: 1\ndescription: x\ndevice: ms2000\nextends: mp285\n")
    message = error_of(str(child), {})
    assert message.startswith(f"{child}:3: device: 'ms2000' cannot extend 'mp285'")
    assert "mp285.yaml" not in message


def test_child_without_device_takes_the_parents_family(tmp_path: Path) -> None:
    child = write(tmp_path, "stage.yaml", "spec: 1\nextends: mp285\n")
    assert load_profile(str(child)).family == "mp285"


@pytest.mark.parametrize(
    ("description", "problem"),
    [
        ("x" * 200, ""),
        ("µ-manipulator, 25 µsteps/µm", ""),
        ("x" * 201, "is longer than 200 characters"),
        ("a\tb", "'a\\tb' is not one line of printable text"),
    ],
)
def test_description_is_one_bounded_line(tmp_path: Path, description: str, problem: str) -> None:
    path = write(tmp_path, "p.yaml", f"spec: 1\nextends: mp285\ndescription: {json.dumps(description)}\n")
    if not problem:
        assert load_profile(str(path)).description == description
    else:
        message = error_of(str(path), {})
        assert message.startswith(f"{path}:3: description: ") and message.endswith(problem)


def test_a_rig_is_not_a_profile(tmp_path: Path) -> None:
    rig = write(tmp_path, "rig.yaml", "spec: 1\ndevices: [{name: a, profile: mp285}]\n")
    assert error_of(str(rig), {}) == f"{rig}: is a rig file, not a profile"
