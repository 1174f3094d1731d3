"""The `ms2000` profile schema: identity, axes, modules, DIP switches and behaviour knobs.

Every field names the rule it implements and says what it means (`stage-emu describe`). Module
plug-ins add their own fields (top level and `knobs`), so a new module or a new build is one module
file plus a small profile YAML that `extends: ms2000`.

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
from typing import Any

from emulator.devices.ms2000.modules import MODULES, known_names
from emulator.profile import line_struct
from emulator.schema import (
    Bool,
    Choice,
    Derived,
    Field,
    Float,
    Int,
    ListOf,
    MapOf,
    SchemaError,
    Str,
    Struct,
    Text,
)
from emulator.schema import Path as SchemaPath
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


def baud_of(sw4: str, sw5: str) -> int:
    return BAUDS[(sw4, sw5)]


def _max_speed(values: Mapping[str, Any]) -> float:
    return round(values["pitch_mm"] * MAX_SPEED_PER_MM_PITCH, 6)


AXIS = Struct(
    "Ms2000Axis",
    (
        Field(
            "pitch_mm",
            Float(0, MAX_PITCH_MM, exclusive_minimum=True),
            6.35,
            "MS-54",
            "lead-screw pitch (sets max speed)",
        ),
        Field("encoder", Choice(("rotary", "linear")), "rotary", "MS-SI-3", "encoder kind"),
        Field(
            "counts_per_mm",
            Float(0, MAX_COUNTS_PER_MM, exclusive_minimum=True),
            45396.0,
            "MS-45",
            "encoder counts per mm (C)",
        ),
        Field(
            "max_speed_mm_s",
            _SPEED,
            Derived(_max_speed, "7.68 × pitch_mm / 6.35"),
            "MS-54",
            "highest settable speed S (mm/s)",
        ),
        Field(
            "speed_mm_s",
            _SPEED,
            Derived(lambda v: round(DEFAULT_SPEED_SHARE * v["max_speed_mm_s"], 6), "67 % of max_speed_mm_s"),
            "MS-54",
            "factory speed S (mm/s)",
        ),
        Field("accel_ms", Int(1, 10000), 70, "MS-55", "factory ramp time AC (ms)"),
        Field("wait_ms", Int(0, 65535), 0, "MS-56", "factory wait time WT after landing (ms)"),
        Field(
            "backlash_mm",
            Float(0, MAX_DISTANCE_MM),
            Derived(lambda v: round(0.04 * v["pitch_mm"] / 6.35, 6), "0.04 × pitch_mm / 6.35"),
            "MS-57",
            "factory anti-backlash distance B (mm)",
        ),
        Field("overshoot_mm", Float(0, MAX_DISTANCE_MM), 0.0, "MS-58", "factory overshoot OS (mm)"),
        Field("drift_error_mm", _POSITIVE_DISTANCE, 0.0004, "MS-59", "factory drift error E (mm)"),
        Field(
            "finish_error_mm",
            _POSITIVE_DISTANCE,
            Derived(lambda v: round(1 / v["counts_per_mm"], 6) or 0.000001, "one count, 6 decimals"),
            "MS-60",
            "factory finish error PC (mm)",
        ),
        Field("maintain", Choice((0, 1, 2, 3, 5)), 0, "MS-61", "factory post-move behaviour MA"),
        Field("runaway_mm", _POSITIVE_DISTANCE, 1.5, "MS-62", "factory servo-error limit RU (mm)"),
        Field("kp", Int(-32768, 32767), 100, "MS-97", "factory KP"),
        Field("ki", Int(-32768, 32767), 20, "MS-97", "factory KI"),
        Field("kd", Int(-32768, 32767), 0, "MS-97", "factory KD"),
        Field("kv", Int(-32768, 32767), 26, "MS-97", "factory KV"),
        Field("ka", Int(-32768, 32767), 0, "MS-97", "factory KA"),
        Field("aa", Int(0, 99), 83, "MS-97", "factory AA (motor-drive alignment)"),
        Field("dac_mm_s", _SPEED, 0.055, "MS-71", "factory D: mm/s per DAC count"),
        Field(
            "unit_multiplier",
            Float(-MAX_UNIT_MULTIPLIER, MAX_UNIT_MULTIPLIER),
            10000.0,
            "MS-44",
            "factory UM: units per mm",
        ),
        Field(
            "soft_lower_mm", _DISTANCE, -110.0, "MS-65", "factory lower soft limit SL (mm from fresh origin)"
        ),
        Field(
            "soft_upper_mm", _DISTANCE, 110.0, "MS-65", "factory upper soft limit SU (mm from fresh origin)"
        ),
        Field("home_mm", _DISTANCE, 1000.0, "MS-68", "factory home position HM (mm from fresh origin)"),
        Field(
            "travel_mm", ListOf(_DISTANCE, length=2), (-60.0, 60.0), "MS-50", "hardware limit switches (mm)"
        ),
        Field(
            "input_device",
            Choice(tuple(INPUT_DEVICES)),
            2,
            "MS-73",
            "manual input: 0, 2 JS_X, 3 JS_Y, 22 wheel",
        ),
        Field("ll_id", Int(1, 254), 24, "MS-114", "factory low-level axis id (LL)"),
    ),
    validate=lambda v, path: _check_axis(v, path),
)


def _check_axis(values: Mapping[str, Any], path: SchemaPath) -> None:
    low, high = values["travel_mm"]
    if low >= high:
        raise SchemaError((*path, "travel_mm"), f"lower end {low:g} is not below upper end {high:g}")
    if values["unit_multiplier"] == 0:
        raise SchemaError((*path, "unit_multiplier"), "must not be 0")
    if values["speed_mm_s"] > values["max_speed_mm_s"]:
        raise SchemaError((*path, "speed_mm_s"), "is above max_speed_mm_s")


DIPS = Struct(
    "Ms2000Dips",
    tuple(
        Field(f"sw{n}", _UPDOWN, "up", rule, doc)
        for n, rule, doc in (
            (1, "Appendix B", "LCD two-column mode"),
            (2, "MS-116", "LCD line 2: up = module status, down = version / LCD text"),
            (3, "Appendix B", "unused"),
            (
                4,
                "MS-2",
                "baud rate bit (with sw5): up/up 9600, down/up 19200, up/down 28800, down/down 115200",
            ),
            (5, "MS-2", "baud rate bit (with sw4)"),
            (6, "Appendix B", "unused"),
            (7, "MS-83", "down inverts joystick Y"),
            (8, "MS-83", "down inverts joystick X"),
        )
    ),
)

BASE_KNOBS = (
    Field("line_mismatch", Choice(("garble", "ignore")), "garble", "MS-4", "host at other line settings"),
    Field(
        "empty_line_reply",
        Choice(("error", "ignore")),
        "error",
        "MS-8",
        "reply to an empty line: :N-1 or none",
    ),
    Field("max_line", Int(1, 65536), 256, "MS-9", "longest command line in bytes; longer lines reply :N-6"),
    Field("ack_trailing_space", Bool(), False, "MS-17", "acknowledge as `:A ` instead of `:A`"),
    Field(
        "reply_shape_overrides",
        MapOf(Str(), Choice(SHAPE_NAMES)),
        {},
        "MS-38",
        "command shortcut -> reply shape of its queries (e.g. OS: colon_axis_A)",
    ),
    Field("reply_trailing_space", Bool(), False, "MS-38", "one space before the terminator of value replies"),
    Field(
        "gate_features_by_version",
        Choice((False,)),
        False,
        "MS-34",
        "gate features by the version string (only false: every feature of a present module works)",
    ),
    Field(
        "landing_ms", Float(0, MAX_MS), 0, "MS-53", "settling time after landing, before the wait time (ms)"
    ),
    Field("status_bit5_up_is_one", Bool(), True, "MS-80", "status bit 5 reads 1 while ramping up"),
    Field("rb_space_after_ack", Bool(), False, "MS-82", "RDSBYTE replies `:A ` before the raw bytes"),
    Field("error_log_clock_marks", Bool(), True, "MS-41", "log code 255 every 10 minutes of uptime"),
    Field("version_trailing_space", Bool(), True, "MS-99", "VERSION reply ends with a space"),
    Field("info_fix_pc_tag", Bool(), False, "MS-106", "INFO prints [PC] instead of the firmware's [PC}"),
    Field("info_absent_axis", Choice(("silent", "error")), "silent", "MS-107", "INFO of an absent axis"),
    Field("vb_silent", Bool(), False, "MS-109", "VB sets produce no reply"),
)


def _knobs() -> Struct:
    module_knobs = tuple(f for cls in MODULES.values() for f in cls.knob_fields)
    return Struct("Ms2000Knobs", BASE_KNOBS + module_knobs)


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


def _line_default(values: Mapping[str, Any]) -> dict[str, Any]:
    dips = values["dip_switches"]
    return {"baud": baud_of(dips.sw4, dips.sw5)}


def _check(values: Mapping[str, Any], path: SchemaPath) -> None:
    axes = values["motor_axes"]
    for i, letter in enumerate(axes):
        if letter not in values["axes"]:
            raise SchemaError((*path, "motor_axes", i), f"axis {letter} has no entry under axes")
    known = known_names()
    for i, module in enumerate(values["modules"]):
        if module not in known:
            raise SchemaError(
                (*path, "modules", i), f"{module!r} is not an emulated module; known: {', '.join(known)}"
            )
    baud = baud_of(values["dip_switches"].sw4, values["dip_switches"].sw5)
    if values["line"].baud != baud:
        raise SchemaError(
            (*path, "line", "baud"),
            f"{values['line'].baud} disagrees with dip_switches sw4/sw5 ({baud}); set the switches instead",
        )
    for key in values["knobs"].reply_shape_overrides:
        if key not in BY_KEY:
            raise SchemaError((*path, "knobs", "reply_shape_overrides", key), "is not a command shortcut")
    ids = [values["axes"][a].ll_id for a in axes]
    if len(set(ids)) != len(ids):
        raise SchemaError((*path, "axes"), "two motor axes share one ll_id")


def build_schema() -> Struct:
    module_fields = tuple(f for cls in MODULES.values() for f in cls.profile_fields)
    return Struct(
        "Ms2000",
        (
            Field(
                "device_id",
                Text(64, ascii=True),
                "ms2000-0001",
                "MS-111",
                "identity of the non-volatile memory",
            ),
            Field("build_name", Text(IDENTITY_LENGTH, ascii=True), "STD_XYZ", "MS-101", "BUILD name"),
            Field(
                "version",
                Text(LCD_WIDTH, ascii=True),
                "USB-9.2k",
                "MS-99",
                "VERSION text (keep a 4-character prefix like USB-)",
            ),
            Field("cdate", Text(20, ascii=True), "Mar 14 2016:17:32:08", "MS-100", "CDATE compile date"),
            Field("who", Text(IDENTITY_LENGTH, ascii=True), "ASI-MS2000-XYBR-Zs-USB", "MS-105", "WHO text"),
            Field(
                "bootldr", Text(IDENTITY_LENGTH, ascii=True), "BootLdr V:1", "MS-102", "BU X boot-loader line"
            ),
            Field("hdwr", Text(IDENTITY_LENGTH, ascii=True), "Hdwr REV.E", "MS-102", "BU X hardware line"),
            Field("cmd_letters", Text(IDENTITY_LENGTH, ascii=True), "XYZFTR", "MS-42", "BU X `CMDs:` line"),
            Field(
                "motor_axes",
                ListOf(_LETTER, min_length=1, max_length=4, unique=True),
                ("X", "Y", "Z"),
                "MS-42",
                "motor axes in hardware order",
            ),
            Field(
                "axes", MapOf(_LETTER, AXIS), DEFAULT_AXES, "MS-45", "per-axis mechanics and factory settings"
            ),
            Field(
                "modules",
                ListOf(Str(), unique=True),
                DEFAULT_MODULES,
                "§9.0",
                "firmware modules, as BU X prints",
            ),
            Field("dip_switches", DIPS, None, "MS-2", "DIP switch positions at power-up"),
            Field("servo_ms", Int(1, 100), 6, "MS-106", "servo loop period (ms)"),
            Field(
                "wheel_um_per_count",
                Float(0, MAX_WHEEL_UM, exclusive_minimum=True),
                0.5,
                "MS-84",
                "focus wheel step (µm)",
            ),
            *module_fields,
            Field(
                "line",
                line_struct((9600, 19200, 28800, 115200), 9600, "MS-1", stop_bits=(1, 2)),
                Derived(_line_default, "baud from dip_switches"),
                "MS-1",
                "main port line settings (baud follows the DIP switches; stop_bits is the SB factory value)",
            ),
            Field("knobs", _knobs(), None, "§A.3", "behaviour knobs"),
        ),
        validate=_check,
    )


SCHEMA = build_schema()
