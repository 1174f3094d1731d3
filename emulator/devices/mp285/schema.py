"""MP-285 profile schema: line, controller, stage and behaviour knobs (docs/mp285.md, App. A).

Every number has a finite range, so e.g. `settle_s: 1e300` is refused at load: durations at most
`MAX_SECONDS` (an hour), `accel_um_s2` at most `MAX_ACCEL_UM_S2` (10 m/s², far beyond the stepper
drive), `z_usteps_per_um` at most `MAX_Z_USTEPS_PER_UM` (travel then still fits 32 bits), positions
in µsteps within 32 bits (the origin through the MP-30 check), `input_buffer_size` at most
`MAX_BUFFER_BYTES` and `coarse_step_quantum_usteps` at most `MAX_QUANTUM_USTEPS` (40 mm).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from emulator.profiles.profile import Config, Line, line_section
from emulator.profiles.schema import (
    Bool,
    Choice,
    Derived,
    Float,
    Int,
    ListOf,
    Nullable,
    Path,
    Schema,
    SchemaError,
    Section,
    Str,
    setting,
)
from protocols import mp285 as proto

BAUDS = (1200, 2400, 4800, 9600, 19200)
#: status dump of a real MP-285, firmware 3.40, at power-on (TV-1)
DUMP_A = "40 00 02 04 07 00 63 00 63 00 14 00 88 13 01 78 70 17 10 27 50 00 00 00 19 00 04 00 C8 00 54 01"
#: status dump of a real MP-285A, firmware 3.02, at power-on (TV-2)
DUMP_B = "62 03 01 01 04 00 14 00 63 00 05 00 88 13 01 78 C4 09 88 13 50 00 00 00 19 00 04 00 DC 05 2E 01"
HEX32 = r"\s*(?:[0-9A-Fa-f]{2}\s*){32}"
TRAVEL_UM = 25_000  # MP-285 axes and any Z
MT800_XY_TRAVEL_UM = 22_000
SIGNATURE_BYTES = {"nul": b"\x00", "zero_char": b"0", "silent": b""}
MAX_SECONDS = 3600.0
MAX_ACCEL_UM_S2 = 1e7
MAX_Z_USTEPS_PER_UM = 1000.0
MAX_BUFFER_BYTES = 65536
MAX_QUANTUM_USTEPS = 1_000_000


def _template_word(offset: int) -> Derived:
    return Derived(
        lambda v: proto.unpack_u16(bytes.fromhex(v["status_template"])[offset : offset + 2]),
        f"the status template's word at offset {offset}",
    )


def _travel(values: Mapping[str, Any]) -> list[int]:
    xy_um = MT800_XY_TRAVEL_UM if values["device_type"] == "mt800" else TRAVEL_UM
    xy = xy_um * proto.XY_USTEPS_PER_UM[values["device_type"]]
    return [xy, xy, proto.round_half_away(TRAVEL_UM * values["z_usteps_per_um"])]


LINE = line_section("Mp285Line", BAUDS, 9600, "MP-1", flow_controls=("none", "rtscts"))


@dataclass(frozen=True)
class Mp285Controller(Schema):
    model: str = setting(Choice(("mp285", "mp285a")), "mp285", "§0.1", "controller model: MP-285 or MP-285A")
    interface: str = setting(
        Choice(("rs232", "usb_vcp")),
        "rs232",
        "MP-1, MP-2",
        "port the host uses: RS-232 connector or the MP-285A's USB virtual COM port",
    )
    require_rtscts: bool = setting(
        Bool(),
        Derived(lambda v: v["interface"] == "usb_vcp", "true on usb_vcp"),
        "MP-7",
        "on usb_vcp, a host without RTS/CTS loses bytes sent while the device is busy",
    )
    status_template: str = setting(
        Str(pattern=HEX32, pattern_text="32 hex bytes"),
        Derived(lambda v: DUMP_B if v["model"] == "mp285a" else DUMP_A, "dump A (MP-285), B (MP-285A)"),
        "MP-60",
        "status block at power-on; FLAGS bit 4 (5 per MP-64), FLAGS_2 bit 2 and bytes 24-31 are computed",
    )
    firmware_version: int = setting(
        Int(0, 0xFFFF), _template_word(30), "MP-60", "VERSION word: firmware × 100"
    )
    step_fields_format: str = setting(
        Choice(("mp285", "mp285a")),
        "mp285",
        "MP-63",
        "STEP_DIV/STEP_MUL as units report them: µsteps per µm and µm per µstep × 100 (mp285), "
        "or the quick reference's nm per 10 µsteps (mp285a)",
    )
    power_on_velocity_word: int = setting(
        Int(0, 0xFFFF),
        _template_word(28),
        "MP-61",
        "V word in force at power-on and after reset (bit 15 high resolution, bits 14-0 µm/s)",
    )
    max_speed_high_um_s: int = setting(
        Int(1, 0x7FFF), proto.MAX_SPEED_HIGH_UM_S, "MP-38", "speed limit at high resolution"
    )
    max_speed_low_um_s: int = setting(
        Int(1, 0x7FFF),
        Derived(lambda v: proto.MAX_SPEED_LOW_UM_S[v["model"]], "6550 (MP-285), 3000 (MP-285A)"),
        "MP-38",
        "speed limit at low resolution",
    )


def speed_limits(controller: Mp285Controller) -> proto.SpeedLimits:
    """The profile's `V` speed limits (MP-38)."""
    return proto.SpeedLimits(controller.max_speed_low_um_s, controller.max_speed_high_um_s)


@dataclass(frozen=True)
class Mp285Stage(Schema):
    device_type: str = setting(
        Choice(("mp285", "mt800")),
        "mp285",
        "MP-28",
        "mechanics: mp285 (25 µsteps/µm) or mt800 XY translator (20 µsteps/µm on X, Y)",
    )
    z_usteps_per_um: float = setting(
        Float(0, MAX_Z_USTEPS_PER_UM, exclusive_minimum=True),
        25,
        "MP-28",
        "µsteps per µm of the Z axis (a focus drive may differ)",
    )
    travel_usteps: tuple[int, ...] = setting(
        ListOf(Int(1, proto.INT32_MAX), length=3),
        Derived(_travel, "axis length × µsteps per µm"),
        "MP-29",
        "length of travel of X, Y, Z in µsteps",
    )
    origin: str = setting(
        Choice(("cot", "bot")), "cot", "MP-30", "origin at centre (cot) or beginning of travel"
    )
    origin_usteps_from_bot: tuple[int, ...] = setting(
        ListOf(Int(), length=3),  # bounded by validate(): positions must fit 32 bits
        Derived(
            lambda v: [length // 2 if v["origin"] == "cot" else 0 for length in v["travel_usteps"]],
            "from origin and travel",
        ),
        "MP-30",
        "origin of X, Y, Z in µsteps from the beginning of travel (any value)",
    )
    power_on_physical_usteps: tuple[int, ...] = setting(
        ListOf(Int(0, proto.INT32_MAX), length=3),
        Derived(lambda v: [length // 2 for length in v["travel_usteps"]], "half the travel"),
        "MP-30",
        "physical position of X, Y, Z at power-on, in µsteps from the beginning of travel",
    )

    def validate(self, path: Path) -> None:
        """MP-30: power-on positions inside travel; reported positions must fit 32 bits."""
        for axis, (length, origin, start) in enumerate(
            zip(self.travel_usteps, self.origin_usteps_from_bot, self.power_on_physical_usteps, strict=True)
        ):
            if not 0 <= start <= length:
                raise SchemaError(
                    (*path, "power_on_physical_usteps", axis),
                    f"{start} is outside the axis travel 0 … {length} µsteps",
                )
            low, high = -origin, length - origin
            if low < proto.INT32_MIN or high > proto.INT32_MAX:
                raise SchemaError(
                    (*path, "origin_usteps_from_bot", axis),
                    f"reported positions {low} … {high} would not fit a signed 32-bit value",
                )


SECONDS = Float(0, MAX_SECONDS)


@dataclass(frozen=True)
class Mp285Knobs(Schema):
    pace_line: bool = setting(Bool(), True, "MP-3", "send one character per character time")
    line_mismatch: str = setting(
        Choice(("garble", "ignore")),
        "garble",
        "MP-6",
        "a host with other framing gets garbled traffic (bit-level model) or clean bytes",
    )
    stray_terminator_reply: str = setting(
        Choice(("cr", "ignore")),
        "cr",
        "MP-20",
        "a lone CR or LF in command position is answered with CR, or ignored",
    )
    input_buffer_size: int = setting(
        Int(1, MAX_BUFFER_BYTES), 64, "MP-23", "bad-frame bytes without CR before error '2'"
    )
    out_of_range: str = setting(
        Choice(("clamp", "error4")),
        "clamp",
        "MP-36",
        "targets outside travel stop at the limit, or reject the move with '4'",
    )
    velocity_over_limit: str = setting(
        Choice(("clamp", "error4")),
        "clamp",
        "MP-39",
        "a V speed over the limit is reduced to it, or rejected with '4'",
    )
    coarse_step_quantum_usteps: int = setting(
        Int(1, MAX_QUANTUM_USTEPS), 1, "MP-42", "at low resolution, displacements round to a multiple of this"
    )
    axis_motion: str = setting(
        Choice(("simultaneous", "sequential")),
        "simultaneous",
        "MP-43",
        "axes move together, or X then Y then Z",
    )
    settle_s: float = setting(SECONDS, 0.15, "MP-44", "time at the target before the move's final CR")
    accel_um_s2: float = setting(
        Float(0, MAX_ACCEL_UM_S2), 0, "MP-45", "acceleration along the longest axis; 0 = none"
    )
    terminators_interrupt_move: bool = setting(
        Bool(), False, "MP-50", "a CR or LF in command position interrupts a move"
    )
    query_interrupts_move: bool = setting(
        Bool(), True, "MP-51", "a c or s during a move halts it (false: answered, the move goes on)"
    )
    move_interrupt_reply: str = setting(
        Choice(("cr", "error8", "error8_4")),
        "cr",
        "MP-53",
        "final reply of a move interrupted by a byte other than ^C",
    )
    reset_deaf_s: float = setting(SECONDS, 0.2, "MP-56", "input is lost for this long after r")
    reset_emits_nul: bool = setting(Bool(), False, "MP-58", "r sends one 00 byte")
    flags_bit5_tracks_move_mode: bool = setting(
        Bool(), False, "MP-64", "status FLAGS bit 5 follows a/b instead of the stored value"
    )
    flags_bit5_relative_is_set: bool = setting(
        Bool(), True, "MP-64", "when bit 5 tracks the mode: set means relative"
    )
    program_vector_types: str = setting(
        Choice(("strict", "lenient")),
        "strict",
        "MP-67",
        "vector descriptors other than move/pause are rejected, or any non-zero one moves",
    )
    k_reply_at_pause: bool = setting(
        Bool(), True, "MP-68", "k and e reply at a pause vector (false: only at the program's end)"
    )
    program_vectors: str = setting(
        Choice(("relative", "follow_mode")),
        "relative",
        "MP-69",
        "move vectors are displacements, or absolute targets in absolute mode",
    )
    program_retention: str = setting(
        Choice(("power_cycle", "reset", "always")),
        "power_cycle",
        "MP-73",
        "stored programs are lost at power cycle, also at r, or never",
    )
    power_on_s: float = setting(SECONDS, 1.0, "MP-76", "silent, deaf start-up time after a power cycle")
    crash_signature: str = setting(
        Choice(tuple(SIGNATURE_BYTES)), "nul", "MP-77", "bytes a crashed unit sends: 00, '0', or nothing"
    )
    crash_recovery: str = setting(
        Choice(("power_cycle", "cr_burst", "ctrl_c")),
        "power_cycle",
        "MP-78",
        "what revives a crashed unit besides a power cycle: 200 CRs or a ^C",
    )
    roe_crash: bool = setting(Bool(), False, "MP-79", "host input shortly after an ROE turn crashes the unit")
    roe_crash_window_s: tuple[float, ...] = setting(
        ListOf(SECONDS, length=2),
        [0.5, 1.0],
        "MP-79",
        "[start, end) seconds after the last ROE click in which host input crashes",
    )
    lockup_incomplete_frame_s: float | None = setting(
        Nullable(Float(0, MAX_SECONDS, exclusive_minimum=True)),
        None,
        "MP-80",
        "a frame left incomplete this long locks the unit until power cycle; null = never",
    )

    def validate(self, path: Path) -> None:
        low, high = self.roe_crash_window_s
        if not low < high:
            raise SchemaError(
                (*path, "roe_crash_window_s"), f"[{low}, {high}) is empty; the start must come first"
            )


@dataclass(frozen=True)
class Mp285Config(Config):
    line: Line = setting(Section(LINE), None, "MP-1", "serial line settings of the device")
    controller: Mp285Controller = setting(
        Section(Mp285Controller), None, "§0.1", "controller model, interface and firmware"
    )
    stage: Mp285Stage = setting(
        Section(Mp285Stage), None, "MP-28", "attached mechanics: units, travel, origin"
    )
    knobs: Mp285Knobs = setting(Section(Mp285Knobs), None, "App. A", "behaviour knobs")

    def validate(self, path: Path) -> None:
        """MP-1, MP-2: line settings per interface; MP-38: the power-on `V` word within its limit."""
        line, controller = self.line, self.controller
        if controller.interface == "usb_vcp":
            fixed = {"baud": 9600, "parity": "none", "stop_bits": 1}
            for key, wanted in fixed.items():
                if getattr(line, key) != wanted:
                    raise SchemaError(
                        (*path, "line", key),
                        f"the USB virtual COM port is fixed at 9600 8N1 (MP-2); set {key}: {wanted}",
                    )
            if line.flow_control != "rtscts":
                raise SchemaError(
                    (*path, "line", "flow_control"), "the USB virtual COM port uses RTS/CTS (MP-2): rtscts"
                )
        elif line.flow_control != "none":
            raise SchemaError(
                (*path, "line", "flow_control"),
                "the RS-232 port is 3-wire without flow control (MP-1): none",
            )
        velocity = proto.Velocity.from_word(controller.power_on_velocity_word)
        limit = speed_limits(controller).limit(velocity.high)
        if velocity.speed > limit:
            raise SchemaError(
                (*path, "controller", "power_on_velocity_word"),
                f"{velocity.describe()} exceeds the {limit} µm/s limit of that resolution (MP-38)",
            )
