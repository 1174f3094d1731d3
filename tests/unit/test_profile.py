"""Profile loading and validation: every error class names file, line and key."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

import tests.support.probe_device  # noqa: F401  (registers the `probe` family)
from emulator.profiles.describe import describe_rows
from emulator.profiles.profile import ProfileError, load_profile
from emulator.profiles.schema import (
    Choice,
    Derived,
    Field,
    Float,
    Int,
    ListOf,
    MapOf,
    Nullable,
    Schema,
    SchemaError,
    Section,
    Str,
    every_error,
    extend,
    required,
    setting,
)

PROBE = Path(__file__).parent.parent / "support" / "probe.yaml"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def error_of(path: Path | str) -> str:
    with pytest.raises(ProfileError) as info:
        load_profile(str(path))
    return str(info.value)


def test_loads_into_frozen_dataclasses() -> None:
    profile = load_profile(str(PROBE))
    assert profile.family == "probe"
    assert profile.line.baud == 9600
    assert profile.config.knobs.pace_line is True
    with pytest.raises(AttributeError):
        profile.line.baud = 19200  # type: ignore[misc]


def test_bad_baud_names_file_line_key_and_choices(tmp_path: Path) -> None:
    path = write(tmp_path, "x.yaml", f"spec: 1\nextends: {PROBE}\nline:\n  baud: 14400\n")
    assert error_of(path) == f"{path}:4: line.baud: 14400 is not one of 1200, 2400, 4800, 9600, 19200, 115200"


def test_unknown_key_lists_allowed_keys(tmp_path: Path) -> None:
    path = write(tmp_path, "x.yaml", "spec: 1\ndevice: probe\nknobs:\n  pace_lin: true\n")
    assert error_of(path).endswith("x.yaml:4: knobs.pace_lin: unknown key; allowed here: pace_line")


def test_wrong_type(tmp_path: Path) -> None:
    path = write(tmp_path, "x.yaml", "spec: 1\ndevice: probe\nknobs:\n  pace_line: 3\n")
    assert error_of(path).endswith("x.yaml:4: knobs.pace_line: 3 is not a boolean (true or false)")


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("device: probe\n", "spec: is required (spec: 1)"),
        ("spec: 2\ndevice: probe\n", "spec: 2 is not a supported version (only 1)"),
        ("spec: 1\n", "device: is required; one of"),
        ("spec: 1\ndevice: toaster\n", "device: 'toaster' is not one of"),
        ("spec: 1\ndevice: probe\ndescription: [1]\n", "description: must be a string"),
        ("- 1\n", "a profile must be a mapping"),
        ("spec: 1\ndevice: probe\nline: {baud: 9600, baud: 4800}\n", "line.baud: duplicate key"),
        ("spec: 1\ndevice: [probe\n", "not valid YAML"),
        ("spec: 1\ndevice: !!python/object:os.system {}\n", "not valid YAML"),
    ],
)
def test_top_level_errors(tmp_path: Path, body: str, expected: str) -> None:
    assert expected in error_of(write(tmp_path, "x.yaml", body))


def test_extends_merges_parent_first(tmp_path: Path) -> None:
    write(
        tmp_path, "base.yaml", "spec: 1\ndevice: probe\ndescription: base\nline: {baud: 4800, stop_bits: 2}\n"
    )
    child = write(tmp_path, "child.yaml", "spec: 1\nextends: base.yaml\nline: {baud: 19200}\n")
    profile = load_profile(str(child))
    assert (profile.line.baud, profile.line.stop_bits) == (19200, 2)
    assert profile.description == "base"
    assert [Path(p).name for p in profile.chain] == ["base.yaml", "child.yaml"]


def test_extends_cycle_is_detected(tmp_path: Path) -> None:
    write(tmp_path, "a.yaml", "spec: 1\nextends: b.yaml\n")
    write(tmp_path, "b.yaml", "spec: 1\nextends: a.yaml\n")
    message = error_of(tmp_path / "a.yaml")
    assert "extends cycle: a -> b -> a" in message
    assert "b.yaml:2: extends" in message


def test_unknown_extends(tmp_path: Path) -> None:
    path = write(tmp_path, "a.yaml", "spec: 1\nextends: nosuchprofile\n")
    assert "a.yaml:2: extends: unknown profile 'nosuchprofile' (bundled profiles:" in error_of(path)


def test_error_in_parent_points_at_parent(tmp_path: Path) -> None:
    write(tmp_path, "base.yaml", "spec: 1\ndevice: probe\nline:\n  parity: mark\n")
    child = write(tmp_path, "child.yaml", "spec: 1\nextends: base.yaml\n")
    assert "base.yaml:4: line.parity: 'mark' is not one of 'none', 'even', 'odd'" in error_of(child)


def test_overrides_apply_last() -> None:
    profile = load_profile(str(PROBE), overrides={"line": {"baud": 115200}})
    assert profile.line.baud == 115200


def test_missing_file() -> None:
    assert "no such profile" in error_of("definitely-not-bundled")


@dataclass(frozen=True)
class Nested(Schema):
    count: int = setting(Int(1, 10), 3, "R-1", "a count")
    ratio: float = setting(Float(0, exclusive_minimum=True), 1.0)
    mode: str = setting(Choice(("a", "b")), "a")
    name: str = setting(Str(max_length=4, pattern=r"[a-z]+", pattern_text="lower-case letters"), "ab")
    axes: tuple[int, ...] = setting(
        ListOf(Int(), length=3), Derived(lambda v: [v["count"]] * 3, "count per axis")
    )
    table: dict[str, int] = setting(MapOf(Str(pattern="[XYZ]", pattern_text="an axis letter"), Int()), {})
    limit: int | None = setting(Nullable(Int(0)), None)


NESTED = Section(Nested)


@pytest.mark.parametrize(
    ("value", "path", "message"),
    [
        ({"count": 0}, ("count",), "0 is out of range (>= 1, <= 10)"),
        ({"count": 2.5}, ("count",), "2.5 is not an integer"),
        ({"count": "3"}, ("count",), "'3' is not an integer"),
        ({"ratio": 0}, ("ratio",), "0 is out of range (> 0)"),
        ({"mode": "c"}, ("mode",), "'c' is not one of 'a', 'b'"),
        ({"name": "abcde"}, ("name",), "'abcde' is longer than 4 characters"),
        ({"name": "AB"}, ("name",), "'AB' is not lower-case letters"),
        ({"axes": [1, 2]}, ("axes",), "has 2 items, expected exactly 3"),
        ({"axes": [1, 2, "x"]}, ("axes", 2), "'x' is not an integer"),
        ({"table": {"Q": 1}}, ("table", "Q"), "'Q' is not an axis letter"),
        ({"limit": -1}, ("limit",), "-1 is out of range (>= 0)"),
        ({"ratio": float("nan")}, ("ratio",), "nan is not a finite number"),
        ({"ratio": float("inf")}, ("ratio",), "inf is not a finite number"),
        ({"count": float("-inf")}, ("count",), "-inf is not a finite number"),
        ({"name": "x" * 100}, ("name",), f"'{'x' * 58}… is longer than 4 characters"),
        ([], (), "[] is not a mapping"),
    ],
)
def test_schema_error_classes(value: object, path: tuple, message: str) -> None:
    with pytest.raises(SchemaError) as info:
        NESTED.check(value, ())
    assert info.value.path == path
    assert info.value.message == message


def test_schema_defaults_and_derived() -> None:
    resolved = NESTED.check({"count": 5, "table": {"X": 1}}, ())
    assert resolved.axes == (5, 5, 5)
    assert resolved.table == {"X": 1}
    assert resolved.limit is None


def test_describe_rows_carry_rule_and_default() -> None:
    rows = load_profile(str(PROBE)).describe()
    by_path = {row.path: row for row in rows}
    assert by_path["line.baud"].rule == "T-1"
    assert by_path["knobs.pace_line"].default is True


@dataclass(frozen=True)
class Axis(Schema):
    pitch: float = setting(Float(0), 6.35, "R-2", "screw pitch")
    gain: int = setting(Int(), 10)


@dataclass(frozen=True)
class Tables(Schema):
    axes: dict[str, Axis] = setting(
        MapOf(Str(), Section(Axis)), {"X": {}, "Z": {"pitch": 1.5}}, "R-3", "per-axis mechanics"
    )
    count: int = setting(Int(), 3)
    double: int = setting(Int(), Derived(lambda v: 2 * v["count"], "twice count"))


def test_describe_rows_flatten_per_key_tables_with_their_defaults() -> None:
    resolved = Section(Tables).check({"axes": {"X": {"gain": 4}, "Z": {"pitch": 1.5}}}, ())
    rows = {row.path: row for row in describe_rows(resolved)}
    assert list(rows) == ["axes.X.pitch", "axes.X.gain", "axes.Z.pitch", "axes.Z.gain", "count", "double"]
    assert (rows["axes.X.gain"].value, rows["axes.X.gain"].default) == (4, 10)
    assert (rows["axes.Z.pitch"].value, rows["axes.Z.pitch"].default, rows["axes.Z.pitch"].rule) == (
        1.5,
        1.5,
        "R-2",
    )
    assert rows["double"].value == 6
    assert str(rows["double"].default) == "(twice count)"


@dataclass(frozen=True)
class Keyed(Schema):
    key: str = required(Str(), "R-4", "the key")
    note: str = setting(Str(), "")
    also: int = required(Int())

    def validate(self, path: tuple[str | int, ...]) -> None:
        if self.key == self.note:
            raise SchemaError((*path, "note"), "repeats the key")


def test_required_fields_and_cross_field_check() -> None:
    with pytest.raises(SchemaError) as info:
        Section(Keyed).check({"also": 1}, ("top",))
    assert (info.value.path, info.value.message) == (("top", "key"), "is required")
    with pytest.raises(SchemaError) as info:
        Section(Keyed).check({"key": "k", "note": "k", "also": 1}, ("top",))
    assert (info.value.path, info.value.message) == (("top", "note"), "repeats the key")
    assert Section(Keyed).check({"key": "k", "also": 2}, ()) == Keyed(key="k", note="", also=2)


@dataclass(frozen=True)
class Outer(Schema):
    axis: Axis = setting(Section(Axis), None, "R-6", "one axis")


def test_extend_adds_run_time_fields_in_place_and_swaps_sections() -> None:
    """How MS2000 modules add their fields: `before` places them, `sections` extends a sub-struct."""
    tables = extend(Tables, [Field("extra", Choice(("a", "b")), "a")], before="count")
    assert [row.path for row in describe_rows(Section(tables).check({}, ()))][-3:] == [
        "extra",
        "count",
        "double",
    ]
    axis = extend(Axis, [Field("ratio", Int(1), 2, "R-5", "added to every axis")])
    outer = Section(extend(Outer, [], sections={"axis": axis})).check({"axis": {"ratio": 3}}, ())
    assert isinstance(outer, Outer) and isinstance(outer.axis, Axis)
    assert [(row.path, row.value, row.rule) for row in describe_rows(outer)][-1] == ("axis.ratio", 3, "R-5")
    with pytest.raises(SchemaError, match="unknown key; allowed here: gain, pitch, ratio"):
        Section(extend(Outer, [], sections={"axis": axis})).check({"axis": {"nope": 1}}, ())


def test_every_problem_of_a_profile_is_raised_in_file_order(tmp_path: Path) -> None:
    """A readable profile's problems come together (`problems`), by line; the message is the first."""
    path = write(
        tmp_path,
        "many.yaml",
        "knobs:\n  pace_line: 3\nline:\n  baud: 14400\n  parity: mark\nspec: 1\ndevice: probe\nzoom: 2\n",
    )
    with pytest.raises(ProfileError) as info:
        load_profile(str(path))
    texts = [p.text.split(": ", 2)[:2] for p in info.value.problems]
    assert texts == [
        [f"{path}:2", "knobs.pace_line"],
        [f"{path}:4", "line.baud"],
        [f"{path}:5", "line.parity"],
        [f"{path}:8", "zoom"],
    ]
    assert str(info.value) == info.value.problems[0].text


def test_problems_of_the_file_come_before_those_of_its_parent(tmp_path: Path) -> None:
    write(tmp_path, "parent.yaml", "spec: 1\ndevice: probe\nknobs:\n  oops: 1\n")
    child = write(tmp_path, "child.yaml", "spec: 1\nextends: parent.yaml\n\n\n\nline: {baud: 1}\n")
    with pytest.raises(ProfileError) as info:
        load_profile(str(child))
    assert [p.text.split(": ")[0] for p in info.value.problems] == [
        f"{child}:6",
        f"{tmp_path / 'parent.yaml'}:4",
    ]


def test_sections_lists_and_maps_report_every_bad_item() -> None:
    @dataclass(frozen=True)
    class Inner(Schema):
        n: int = setting(Int(0, 9), 0)

    @dataclass(frozen=True)
    class Outer(Schema):
        items: tuple[int, ...] = setting(ListOf(Int(0, 9)), ())
        table: dict[str, Inner] = setting(MapOf(Str(), Section(Inner)), {})
        size: float = setting(Float(0, 1), 0.5)

    value = {"items": [1, 10, 2, 11], "table": {"a": {"n": 12}, "b": {"n": 3, "m": 1}}, "size": 2, "x": 0}
    with pytest.raises(SchemaError) as info:
        Section(Outer).check(value, ())
    assert [e.path for e in every_error(info.value)] == [
        ("x",),
        ("items", 1),
        ("items", 3),
        ("table", "a", "n"),
        ("table", "b", "m"),
        ("size",),
    ]
    assert info.value.path == ("x",)  # as one SchemaError it is the first
