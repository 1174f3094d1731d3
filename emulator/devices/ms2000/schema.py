"""The `ms2000` profile schema: identity, axes, modules, DIP switches and behaviour knobs.

Every field names the rule it implements and says what it means (`stage-emu describe`). Module
plug-ins add their own fields (top level and `knobs`), so a new module or a new build is one module
file plus a small profile YAML that `extends: ms2000`. Those fields are known only once the modules
have registered (a test registers one of its own), so `SCHEMA` is `Ms2000Config` extended at run time
(`build_schema`): the controller reads the static fields typed, a module its own ones untyped
(`ModuleOwner.cfg`, `ModuleOwner.knobs`).

Every number has a finite range, far beyond any ASI stage yet small enough that encoder counts stay
exact in floating point: pitch up to `MAX_PITCH_MM`, encoder resolution up to `MAX_COUNTS_PER_MM`
(1 nm), speeds up to `MAX_SPEED_MM_S`, distances and positions within ±`MAX_DISTANCE_MM` (10 m),
`unit_multiplier` within ±`MAX_UNIT_MULTIPLIER`, times up to `MAX_MS` (an hour).

Identity strings the firmware prints are printable ASCII of bounded length: `version` at most
`LCD_WIDTH` (20, the LCD line that shows it with DIP switch 2 down, MS-116, MS-99), `cdate` 20
(its `Mmm dd yyyy:hh:mm:ss` format, MS-100), the other lines (BU, BU X, WHO: MS-101, MS-102,
MS-105) at most `IDENTITY_LENGTH` (32; the longest known, WHO, is 22) and `device_id` at most 64.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from emulator.devices.ms2000.modules import MODULES, known_names
from emulator.devices.ms2000.sections import (
    BAUDS,
    INPUT_DEVICES,
    LETTER,
    MAX_SPEED_PER_MM_PITCH,
    MAX_WHEEL_UM,
    Ms2000Axis,
    Ms2000Dips,
    Ms2000Knobs,
    baud_of,
)
from emulator.profiles.profile import Config, Line, line_section
from emulator.profiles.schema import (
    Derived,
    Float,
    Int,
    ListOf,
    MapOf,
    Path,
    SchemaError,
    Section,
    Str,
    Text,
    extend,
    setting,
)
from protocols.ms2000 import BY_KEY

#: the static sections (sections.py) are public here too, as the whole profile's parts
__all__ = [
    "BAUDS",
    "DEFAULT_AXES",
    "DEFAULT_MODULES",
    "IDENTITY_LENGTH",
    "INPUT_DEVICES",
    "LCD_WIDTH",
    "LINE",
    "MAX_SPEED_PER_MM_PITCH",
    "SCHEMA",
    "Ms2000Axis",
    "Ms2000Config",
    "Ms2000Dips",
    "Ms2000Knobs",
    "baud_of",
    "build_schema",
]

LCD_WIDTH = 20
IDENTITY_LENGTH = 32


DEFAULT_AXES = {
    "X": {"input_device": 2, "ll_id": 24, "aa": 83},
    "Y": {"input_device": 3, "ll_id": 25, "aa": 78, "travel_mm": [-40.0, 40.0]},
    "Z": {
        "pitch_mm": 1.5875,
        "counts_per_mm": 20000.0,
        "accel_ms": 50,
        "drift_error_mm": 0.0002,
        "kp": 500,
        "ki": 5,
        "kv": 39,
        "aa": 59,
        "dac_mm_s": 0.0075,
        "travel_mm": [-10.0, 10.0],
        "input_device": 22,
        "ll_id": 26,
    },
}
DEFAULT_MODULES = ("LL COMMANDS", "RING BUFFER", "INO_INT", "LED DIMMER")
LINE = line_section("Ms2000Line", (9600, 19200, 28800, 115200), 9600, "MS-1", stop_bits=(1, 2))


def _line_default(values: Mapping[str, Any]) -> dict[str, Any]:
    dips = values["dip_switches"]
    return {"baud": baud_of(dips.sw4, dips.sw5)}


@dataclass(frozen=True)
class Ms2000Config(Config):
    """The profile without module fields (`build_schema` adds them before `line`)."""

    device_id: str = setting(
        Text(64, ascii=True), "ms2000-0001", "MS-111", "identity of the non-volatile memory"
    )
    build_name: str = setting(Text(IDENTITY_LENGTH, ascii=True), "STD_XYZ", "MS-101", "BUILD name")
    version: str = setting(
        Text(LCD_WIDTH, ascii=True),
        "USB-9.2k",
        "MS-99",
        "VERSION text (keep a 4-character prefix like USB-)",
    )
    cdate: str = setting(Text(20, ascii=True), "Mar 14 2016:17:32:08", "MS-100", "CDATE compile date")
    who: str = setting(Text(IDENTITY_LENGTH, ascii=True), "ASI-MS2000-XYBR-Zs-USB", "MS-105", "WHO text")
    bootldr: str = setting(
        Text(IDENTITY_LENGTH, ascii=True), "BootLdr V:1", "MS-102", "BU X boot-loader line"
    )
    hdwr: str = setting(Text(IDENTITY_LENGTH, ascii=True), "Hdwr REV.E", "MS-102", "BU X hardware line")
    cmd_letters: str = setting(Text(IDENTITY_LENGTH, ascii=True), "XYZFTR", "MS-42", "BU X `CMDs:` line")
    motor_axes: tuple[str, ...] = setting(
        ListOf(LETTER, min_length=1, max_length=4, unique=True),
        ("X", "Y", "Z"),
        "MS-42",
        "motor axes in hardware order",
    )
    axes: dict[str, Ms2000Axis] = setting(
        MapOf(LETTER, Section(Ms2000Axis)), DEFAULT_AXES, "MS-45", "per-axis mechanics and factory settings"
    )
    modules: tuple[str, ...] = setting(
        ListOf(Str(), unique=True), DEFAULT_MODULES, "§9.0", "firmware modules, as BU X prints"
    )
    dip_switches: Ms2000Dips = setting(Section(Ms2000Dips), None, "MS-2", "DIP switch positions at power-up")
    servo_ms: int = setting(Int(1, 100), 6, "MS-106", "servo loop period (ms)")
    wheel_um_per_count: float = setting(
        Float(0, MAX_WHEEL_UM, exclusive_minimum=True), 0.5, "MS-84", "focus wheel step (µm)"
    )
    line: Line = setting(
        Section(LINE),
        Derived(_line_default, "baud from dip_switches"),
        "MS-1",
        "main port line settings (baud follows the DIP switches; stop_bits is the SB factory value)",
    )
    knobs: Ms2000Knobs = setting(Section(Ms2000Knobs), None, "§A.3", "behaviour knobs")

    def validate(self, path: Path) -> None:
        for i, letter in enumerate(self.motor_axes):
            if letter not in self.axes:
                raise SchemaError((*path, "motor_axes", i), f"axis {letter} has no entry under axes")
        known = known_names()
        for i, module in enumerate(self.modules):
            if module not in known:
                raise SchemaError(
                    (*path, "modules", i), f"{module!r} is not an emulated module; known: {', '.join(known)}"
                )
        baud = baud_of(self.dip_switches.sw4, self.dip_switches.sw5)
        if self.line.baud != baud:
            raise SchemaError(
                (*path, "line", "baud"),
                f"{self.line.baud} disagrees with dip_switches sw4/sw5 ({baud}); set the switches instead",
            )
        for key in self.knobs.reply_shape_overrides:
            if key not in BY_KEY:
                raise SchemaError((*path, "knobs", "reply_shape_overrides", key), "is not a command shortcut")
        ids = [self.axes[a].ll_id for a in self.motor_axes]
        if len(set(ids)) != len(ids):
            raise SchemaError((*path, "axes"), "two motor axes share one ll_id")


def build_schema() -> type[Ms2000Config]:
    """`Ms2000Config` with the fields of every registered module, whichever modules a profile lists:
    `profile_fields` just before `line` (where `describe` has always listed them), `knob_fields`
    under `knobs`."""
    knobs = extend(Ms2000Knobs, [f for cls in MODULES.values() for f in cls.knob_fields])
    module_fields = [f for cls in MODULES.values() for f in cls.profile_fields]
    return extend(Ms2000Config, module_fields, before="line", sections={"knobs": knobs})


SCHEMA = build_schema()
