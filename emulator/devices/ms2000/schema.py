"""The `ms2000` profile schema: identity, axes, modules, DIP switches and behaviour knobs.

Every field names the rule it implements and says what it means (`stage-emu describe`). Module
plug-ins add their own fields (top level and `knobs`), so a new module or a new build is one module
file plus a small profile YAML that `extends: ms2000`. Those fields are known only once the modules
have registered (a test registers one of its own), so `SCHEMA` is `Ms2000Config` extended at run time
(`build_schema`): the controller reads the static fields typed, a module its own ones untyped
(`ModuleHost.cfg`, `ModuleHost.knobs`).

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
from emulator.profile import Config, Line, line_section
from emulator.schema import (
    Bool,
    Choice,
    Derived,
    Float,
    Int,
    ListOf,
    MapOf,
    Path,
    Schema,
    SchemaError,
    Section,
    Str,
    Text,
    extend,
    setting,
)
from protocols.ms2000 import BY_KEY, SHAPE_NAMES

#: MS-2: DIP switches 4 and 5 select the baud rate
BAUDS = {("up", "up"): 9600, ("down", "down"): 115200, ("down", "up"): 19200, ("up", "down"): 28800}
#: MS-54: 7.68 mm/s maximum for a 6.35 mm lead screw, scaling with the pitch
MAX_SPEED_PER_MM_PITCH = 7.68 / 6.35
DEFAULT_SPEED_SHARE = 0.67
MAX_PITCH_MM = 100.0
MAX_COUNTS_PER_MM = 1e6
MAX_SPEED_MM_S = 1000.0
MAX_DISTANCE_MM = 10_000.0
MAX_UNIT_MULTIPLIER = 1e6
MAX_MS = 3_600_000.0
MAX_WHEEL_UM = 1000.0
LCD_WIDTH = 20
IDENTITY_LENGTH = 32
INPUT_DEVICES = {0: "NONE", 2: "JS_X", 3: "JS_Y", 22: "WHEEL"}

_LETTER = Str(pattern=r"[A-Z]", pattern_text="one upper-case letter")
_UPDOWN = Choice(("up", "down"))
_DISTANCE = Float(-MAX_DISTANCE_MM, MAX_DISTANCE_MM)
_POSITIVE_DISTANCE = Float(0, MAX_DISTANCE_MM, exclusive_minimum=True)
_SPEED = Float(0, MAX_SPEED_MM_S, exclusive_minimum=True)
_FACTORY_GAIN = Int(-32768, 32767)


def baud_of(sw4: str, sw5: str) -> int:
    return BAUDS[(sw4, sw5)]


def _max_speed(values: Mapping[str, Any]) -> float:
    return round(values["pitch_mm"] * MAX_SPEED_PER_MM_PITCH, 6)


@dataclass(frozen=True)
class Ms2000Axis(Schema):
    pitch_mm: float = setting(
        Float(0, MAX_PITCH_MM, exclusive_minimum=True), 6.35, "MS-54", "lead-screw pitch (sets max speed)"
    )
    encoder: str = setting(Choice(("rotary", "linear")), "rotary", "MS-SI-3", "encoder kind")
    counts_per_mm: float = setting(
        Float(0, MAX_COUNTS_PER_MM, exclusive_minimum=True), 45396.0, "MS-45", "encoder counts per mm (C)"
    )
    max_speed_mm_s: float = setting(
        _SPEED, Derived(_max_speed, "7.68 × pitch_mm / 6.35"), "MS-54", "highest settable speed S (mm/s)"
    )
    speed_mm_s: float = setting(
        _SPEED,
        Derived(lambda v: round(DEFAULT_SPEED_SHARE * v["max_speed_mm_s"], 6), "67 % of max_speed_mm_s"),
        "MS-54",
        "factory speed S (mm/s)",
    )
    accel_ms: int = setting(Int(1, 10000), 70, "MS-55", "factory ramp time AC (ms)")
    wait_ms: int = setting(Int(0, 65535), 0, "MS-56", "factory wait time WT after landing (ms)")
    backlash_mm: float = setting(
        Float(0, MAX_DISTANCE_MM),
        Derived(lambda v: round(0.04 * v["pitch_mm"] / 6.35, 6), "0.04 × pitch_mm / 6.35"),
        "MS-57",
        "factory anti-backlash distance B (mm)",
    )
    overshoot_mm: float = setting(Float(0, MAX_DISTANCE_MM), 0.0, "MS-58", "factory overshoot OS (mm)")
    drift_error_mm: float = setting(_POSITIVE_DISTANCE, 0.0004, "MS-59", "factory drift error E (mm)")
    finish_error_mm: float = setting(
        _POSITIVE_DISTANCE,
        Derived(lambda v: round(1 / v["counts_per_mm"], 6) or 0.000001, "one count, 6 decimals"),
        "MS-60",
        "factory finish error PC (mm)",
    )
    maintain: int = setting(Choice((0, 1, 2, 3, 5)), 0, "MS-61", "factory post-move behaviour MA")
    runaway_mm: float = setting(_POSITIVE_DISTANCE, 1.5, "MS-62", "factory servo-error limit RU (mm)")
    kp: int = setting(_FACTORY_GAIN, 100, "MS-97", "factory KP")
    ki: int = setting(_FACTORY_GAIN, 20, "MS-97", "factory KI")
    kd: int = setting(_FACTORY_GAIN, 0, "MS-97", "factory KD")
    kv: int = setting(_FACTORY_GAIN, 26, "MS-97", "factory KV")
    ka: int = setting(_FACTORY_GAIN, 0, "MS-97", "factory KA")
    aa: int = setting(Int(0, 99), 83, "MS-97", "factory AA (motor-drive alignment)")
    dac_mm_s: float = setting(_SPEED, 0.055, "MS-71", "factory D: mm/s per DAC count")
    unit_multiplier: float = setting(
        Float(-MAX_UNIT_MULTIPLIER, MAX_UNIT_MULTIPLIER), 10000.0, "MS-44", "factory UM: units per mm"
    )
    soft_lower_mm: float = setting(
        _DISTANCE, -110.0, "MS-65", "factory lower soft limit SL (mm from fresh origin)"
    )
    soft_upper_mm: float = setting(
        _DISTANCE, 110.0, "MS-65", "factory upper soft limit SU (mm from fresh origin)"
    )
    home_mm: float = setting(_DISTANCE, 1000.0, "MS-68", "factory home position HM (mm from fresh origin)")
    travel_mm: tuple[float, ...] = setting(
        ListOf(_DISTANCE, length=2), (-60.0, 60.0), "MS-50", "hardware limit switches (mm)"
    )
    input_device: int = setting(
        Choice(tuple(INPUT_DEVICES)), 2, "MS-73", "manual input: 0, 2 JS_X, 3 JS_Y, 22 wheel"
    )
    ll_id: int = setting(Int(1, 254), 24, "MS-114", "factory low-level axis id (LL)")

    def validate(self, path: Path) -> None:
        low, high = self.travel_mm
        if low >= high:
            raise SchemaError((*path, "travel_mm"), f"lower end {low:g} is not below upper end {high:g}")
        if self.unit_multiplier == 0:
            raise SchemaError((*path, "unit_multiplier"), "must not be 0")
        if self.speed_mm_s > self.max_speed_mm_s:
            raise SchemaError((*path, "speed_mm_s"), "is above max_speed_mm_s")


@dataclass(frozen=True)
class Ms2000Dips(Schema):
    sw1: str = setting(_UPDOWN, "up", "Appendix B", "LCD two-column mode")
    sw2: str = setting(_UPDOWN, "up", "MS-116", "LCD line 2: up = module status, down = version / LCD text")
    sw3: str = setting(_UPDOWN, "up", "Appendix B", "unused")
    sw4: str = setting(
        _UPDOWN,
        "up",
        "MS-2",
        "baud rate bit (with sw5): up/up 9600, down/up 19200, up/down 28800, down/down 115200",
    )
    sw5: str = setting(_UPDOWN, "up", "MS-2", "baud rate bit (with sw4)")
    sw6: str = setting(_UPDOWN, "up", "Appendix B", "unused")
    sw7: str = setting(_UPDOWN, "up", "MS-83", "down inverts joystick Y")
    sw8: str = setting(_UPDOWN, "up", "MS-83", "down inverts joystick X")


@dataclass(frozen=True)
class Ms2000Knobs(Schema):
    """The base knobs; `build_schema` adds the modules' `knob_fields`."""

    line_mismatch: str = setting(
        Choice(("garble", "ignore")), "garble", "MS-4", "host at other line settings"
    )
    empty_line_reply: str = setting(
        Choice(("error", "ignore")), "error", "MS-8", "reply to an empty line: :N-1 or none"
    )
    max_line: int = setting(
        Int(1, 65536), 256, "MS-9", "longest command line in bytes; longer lines reply :N-6"
    )
    number_values: str = setting(
        Choice(("prefix", "whole")),
        "prefix",
        "MS-25",
        "a value is the number it starts with, as C's strtod reads it (`X=50?` is 50), or only a "
        "value that is a number as a whole (else missing, 0)",
    )
    ack_trailing_space: bool = setting(Bool(), False, "MS-17", "acknowledge as `:A ` instead of `:A`")
    reply_shape_overrides: dict[str, str] = setting(
        MapOf(Str(), Choice(SHAPE_NAMES)),
        {},
        "MS-38",
        "command shortcut -> reply shape of its queries (e.g. OS: colon_axis_A)",
    )
    reply_trailing_space: bool = setting(
        Bool(), False, "MS-38", "one space before the terminator of value replies"
    )
    landing_ms: float = setting(
        Float(0, MAX_MS), 0, "MS-53", "settling time after landing, before the wait time (ms)"
    )
    status_bit5_up_is_one: bool = setting(Bool(), True, "MS-80", "status bit 5 reads 1 while ramping up")
    rb_space_after_ack: bool = setting(Bool(), False, "MS-82", "RDSBYTE replies `:A ` before the raw bytes")
    error_log_clock_marks: bool = setting(Bool(), True, "MS-41", "log code 255 every 10 minutes of uptime")
    version_trailing_space: bool = setting(Bool(), True, "MS-99", "VERSION reply ends with a space")
    info_fix_pc_tag: bool = setting(
        Bool(), False, "MS-106", "INFO prints [PC] instead of the firmware's [PC}"
    )
    info_absent_axis: str = setting(Choice(("silent", "error")), "silent", "MS-107", "INFO of an absent axis")
    vb_silent: bool = setting(Bool(), False, "MS-109", "VB sets produce no reply")
    knob_speeds_need_module: bool = setting(
        Bool(), False, "MS-KNOB-1", "JS F/T (side-knob speeds) reply :N-2 unless XY KNOBS is in the build"
    )


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
        ListOf(_LETTER, min_length=1, max_length=4, unique=True),
        ("X", "Y", "Z"),
        "MS-42",
        "motor axes in hardware order",
    )
    axes: dict[str, Ms2000Axis] = setting(
        MapOf(_LETTER, Section(Ms2000Axis)), DEFAULT_AXES, "MS-45", "per-axis mechanics and factory settings"
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
