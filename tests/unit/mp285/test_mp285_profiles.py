"""The mp285 family: bundled profiles, schema defaults and load-time checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from emulator.profiles.profile import ProfileError, load_profile
from emulator.profiles.registry import family

BUNDLED = ("mp285", "mp285-mt800", "mp285a", "mp285a-v302", "mp285a-qr", "mp285a-rs232")


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_profiles_load_with_a_description(name: str) -> None:
    profile = load_profile(name)
    assert profile.family == "mp285"
    assert profile.description and "\n" not in profile.description


def test_family_registered() -> None:
    fam = family("mp285")
    assert fam is not None and fam.summary.startswith("Sutter MP-285")


def test_every_field_has_a_rule_and_a_meaning() -> None:
    """`stage-emu describe` shows each key with its rule ID and meaning."""
    rows = load_profile("mp285").describe()
    assert len(rows) > 40
    missing = [row.path for row in rows if not row.rule or not row.doc]
    assert missing == []


APPENDIX_A = [
    "model",
    "interface",
    "baud",
    "stop_bits",
    "parity",
    "pace_line",
    "line_mismatch",
    "require_rtscts",
    "stray_terminator_reply",
    "input_buffer_size",
    "device_type",
    "z_usteps_per_um",
    "travel_usteps",
    "origin",
    "origin_usteps_from_bot",
    "power_on_physical_usteps",
    "out_of_range",
    "max_speed_high_um_s",
    "max_speed_low_um_s",
    "velocity_over_limit",
    "power_on_velocity_word",
    "coarse_step_quantum_usteps",
    "axis_motion",
    "settle_s",
    "accel_um_s2",
    "terminators_interrupt_move",
    "query_interrupts_move",
    "move_interrupt_reply",
    "reset_deaf_s",
    "reset_emits_nul",
    "step_fields_format",
    "flags_bit5_tracks_move_mode",
    "flags_bit5_relative_is_set",
    "status_template",
    "program_vector_types",
    "k_reply_at_pause",
    "program_vectors",
    "program_retention",
    "power_on_s",
    "crash_signature",
    "crash_recovery",
    "roe_crash",
    "roe_crash_window_s",
    "lockup_incomplete_frame_s",
]


def test_every_appendix_a_knob_is_a_profile_key() -> None:
    leaves = {row.path.rsplit(".", 1)[-1] for row in load_profile("mp285").describe()}
    assert set(APPENDIX_A) - leaves == set()


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("mp285", {"word": 0x00C8, "low": 6550, "rtscts": False, "format": "mp285", "version": 340}),
        ("mp285a", {"word": 0x05DC, "low": 3000, "rtscts": True, "format": "mp285", "version": 302}),
        ("mp285a-v302", {"word": 0x05DC, "low": 3000, "rtscts": True, "format": "mp285", "version": 302}),
        ("mp285a-qr", {"word": 0x05DC, "low": 3000, "rtscts": True, "format": "mp285a", "version": 302}),
        ("mp285a-rs232", {"word": 0x05DC, "low": 3000, "rtscts": False, "format": "mp285", "version": 302}),
    ],
)
def test_per_model_defaults(name: str, expected: dict) -> None:
    """§0.1, MP-38, MP-61, MP-63 (every bundled profile but mp285a-qr reports 25/4), MP-7."""
    controller = load_profile(name).config.controller
    got = {
        "word": controller.power_on_velocity_word,
        "low": controller.max_speed_low_um_s,
        "rtscts": controller.require_rtscts,
        "format": controller.step_fields_format,
        "version": controller.firmware_version,
    }
    assert got == expected


@pytest.mark.parametrize(
    ("name", "travel", "origin"),
    [
        ("mp285", (625_000,) * 3, (312_500,) * 3),
        ("mp285-mt800", (440_000, 440_000, 625_000), (220_000, 220_000, 312_500)),
    ],
)
def test_travel_and_origin(name: str, travel: tuple, origin: tuple) -> None:
    """MP-29, MP-30: travel from length × factor; COT origin at half travel."""
    stage = load_profile(name).config.stage
    assert stage.travel_usteps == travel
    assert stage.origin_usteps_from_bot == origin
    assert stage.power_on_physical_usteps == origin
    bot = load_profile(name, {"stage": {"origin": "bot"}}).config.stage
    assert bot.origin_usteps_from_bot == (0, 0, 0)


def test_custom_z_factor_scales_z_travel() -> None:
    """MP-28: a focus drive on Z with its own factor."""
    stage = load_profile("mp285-mt800", {"stage": {"z_usteps_per_um": 50}}).config.stage
    assert stage.travel_usteps == (440_000, 440_000, 1_250_000)


def error_of(name: str, overrides: dict) -> str:
    with pytest.raises(ProfileError) as info:
        load_profile(name, overrides)
    return str(info.value)


@pytest.mark.parametrize(
    ("name", "overrides", "message"),
    [
        ("mp285a", {"line": {"baud": 19200}}, "line.baud: the USB virtual COM port is fixed at 9600 8N1"),
        ("mp285a", {"line": {"stop_bits": 2}}, "line.stop_bits: the USB virtual COM port is fixed"),
        ("mp285a", {"line": {"parity": "odd"}}, "line.parity: the USB virtual COM port is fixed"),
        ("mp285a", {"line": {"flow_control": "none"}}, "line.flow_control: the USB virtual COM port uses"),
        ("mp285", {"line": {"flow_control": "rtscts"}}, "line.flow_control: the RS-232 port is 3-wire"),
        ("mp285", {"line": {"data_bits": 7}}, "line.data_bits: 7 is not one of 8"),
        ("mp285", {"line": {"baud": 115200}}, "line.baud: 115200 is not one of"),
        (
            "mp285",
            {"stage": {"origin_usteps_from_bot": [3_000_000_000, 0, 0]}},
            "stage.origin_usteps_from_bot[0]: reported positions",
        ),
        (
            "mp285",
            {"stage": {"power_on_physical_usteps": [0, 700_000, 0]}},
            "stage.power_on_physical_usteps[1]: 700000 is outside the axis travel",
        ),
        (
            "mp285",
            {"controller": {"power_on_velocity_word": 0x9000}},
            "controller.power_on_velocity_word: 4096 µm/s high",
        ),
        ("mp285", {"controller": {"status_template": "00 11"}}, "controller.status_template"),
        (
            "mp285",
            {"knobs": {"roe_crash_window_s": [1.0, 0.5]}},
            "knobs.roe_crash_window_s: [1.0, 0.5) is empty",
        ),
        ("mp285", {"knobs": {"settle": 1}}, "knobs.settle: unknown key"),
        ("mp285", {"knobs": {"settle_s": 1e300}}, "knobs.settle_s: 1e+300 is out of range (>= 0, <= 3600)"),
        ("mp285", {"knobs": {"settle_s": float("nan")}}, "knobs.settle_s: nan is not a finite number"),
        ("mp285", {"knobs": {"power_on_s": float("inf")}}, "knobs.power_on_s: inf is not a finite number"),
        ("mp285", {"knobs": {"accel_um_s2": 1e8}}, "knobs.accel_um_s2: 100000000.0 is out of range"),
        ("mp285", {"knobs": {"roe_crash_window_s": [0, 1e9]}}, "knobs.roe_crash_window_s[1]: 1000000000.0"),
        ("mp285", {"knobs": {"lockup_incomplete_frame_s": 4000}}, "(> 0, <= 3600)"),
        ("mp285", {"stage": {"z_usteps_per_um": 1e300}}, "stage.z_usteps_per_um: 1e+300 is out of range"),
        ("mp285", {"knobs": {"input_buffer_size": 10**6}}, "knobs.input_buffer_size: 1000000 is out of"),
    ],
)
def test_load_time_checks(name: str, overrides: dict, message: str) -> None:
    """MP-1, MP-2 (line per interface), MP-30 (32-bit, travel), MP-38 (power-on word)."""
    assert message in error_of(name, overrides)


def test_profile_file_extending_a_bundled_one(tmp_path: Path) -> None:
    path = tmp_path / "rig-stage.yaml"
    path.write_text("spec: 1\ndevice: mp285\nextends: mp285\nknobs:\n  settle_s: 0.05\n")
    profile = load_profile(str(path))
    assert profile.config.knobs.settle_s == 0.05
    assert profile.config.controller.firmware_version == 340


def test_step_fields_default_is_what_units_report() -> None:
    """MP-63: the default format is `mp285` whatever the model; only `mp285a-qr` asks for 400/400."""
    controller = load_profile("mp285", {"controller": {"model": "mp285a"}}).config.controller
    assert controller.step_fields_format == "mp285"


def test_describe_shows_the_finite_ranges() -> None:
    """Every duration, speed and factor shows its range in `stage-emu describe`."""
    types = {row.path: row.type for row in load_profile("mp285").describe()}
    assert types["knobs.settle_s"] == "number >= 0, <= 3600"
    assert types["knobs.accel_um_s2"] == "number >= 0, <= 1e+07"
    assert types["stage.z_usteps_per_um"] == "number > 0, <= 1000"
    assert types["knobs.lockup_incomplete_frame_s"] == "number > 0, <= 3600 or null"
