"""The static sections of the `ms2000` profile: one axis, the DIP switches and the behaviour knobs,
with the ranges their numbers keep to (schema.py says why). They need no module, so the axis and
the controller's parts read their types from here without reaching the module plug-ins that
schema.py merges in.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from emulator.profiles.schema import (
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
    Str,
    setting,
)
from protocols.ms2000 import SHAPE_NAMES

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
INPUT_DEVICES = {0: "NONE", 2: "JS_X", 3: "JS_Y", 22: "WHEEL"}

LETTER = Str(pattern=r"[A-Z]", pattern_text="one upper-case letter")
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
