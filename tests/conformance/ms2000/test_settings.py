"""Settings, reply shapes and number formats (§3, §6.2, §6.4, §6.8, §7): TV-11, TV-12, TV-14,
TV-18…TV-20, TV-39…TV-44, TV-46, TV-57, TV-58, TV-62…TV-64, TV-111, TV-112, TV-114."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import pytest

from tests.conformance.ms2000.conftest import ACK, Host, Step

VECTORS = [
    pytest.param([(b"S X=4.69\r", ACK), (b"S X?\r", b":A X=4.690000\r\n")], id="tv011_speed_read_back"),
    pytest.param(
        [(b"AC ACX=25.000000 \r", ACK), (b"AC X? Y?\r", b":X=25 Y=70 A\r\n")], id="tv014_accel_prefixed_key"
    ),
    pytest.param(
        [
            (b"S X=10000\r", ACK),
            (b"S X?\r", b":A X=7.680000\r\n"),
            (b"S Z=99\r", ACK),
            (b"S Z?\r", b":A Z=1.920000\r\n"),
        ],
        id="tv018_speed_clamped_to_maximum",
    ),
    pytest.param(
        [(b"S Z?\r", b":A Z=1.286400\r\n"), (b"S X=0\r", b":N-4\r\n")], id="tv019_speed_default_and_zero"
    ),
    pytest.param([(b"S X=1.23456789\r", ACK), (b"S X?\r", b":A X=1.234568\r\n")], id="tv020_six_decimals"),
    pytest.param(
        [
            (b"E X=.0004\r", ACK),
            (b"E X?\r", b":X=0.000400 A\r\n"),
            (b"E X=0\r", ACK),
            (b"E X?\r", b":X=0.000400 A\r\n"),
        ],
        id="tv040_drift_error",
    ),
    pytest.param(
        [
            (b"PC X?\r", b":A X=0.000022\r\n"),
            (b"PC PCX=0.000001 \r", ACK),
            (b"PC X?\r", b":A X=0.000001\r\n"),
        ],
        id="tv041_finish_error",
    ),
    pytest.param(
        [
            (b"AC X=50 Y=50 Z=50\r", ACK),
            (b"AC X? Y? Z?\r", b":X=50 Y=50 Z=50 A\r\n"),
            (b"AC X=0\r", b":N-4\r\n"),
        ],
        id="tv044_accel",
    ),
    pytest.param(
        [
            (b"AA X? Y? Z?\r", b":A X=83 Y=78 Z=59\r\n"),
            (b"KV Z?\r", b":A Z=39\r\n"),
            (b"KA Z?\r", b":A Z=0\r\n"),
            (b"D X?\r", b":A X=0.055000\r\n"),
            (b"KP X?\r", b":A X=100\r\n"),
            (b"EP X=2\r", b":N-4\r\n"),
        ],
        id="tv046_servo_settings",
    ),
    pytest.param(
        [(b"J X?\r", b":A X=2\r\n"), (b"J X-\r", ACK), (b"RS X\r", b":A 2\r\n"), (b"J X=5\r", b":N-4\r\n")],
        id="tv057_joystick_assignment",
    ),
    pytest.param(
        [
            (b"JS X? Y?\r", b":A JS_FAST=100 JS_SLOW=5\r\n"),
            (b"JS X=0\r", b":N-4\r\n"),
            (b"JS Y=-50\r", ACK),
            (b"JS Y? Z? F? T?\r", b":A JS_SLOW=-50 JS_WHEEL=100.000000 KNOB_SLOW=1.000000 KNOB_MULT=4\r\n"),
            (b"JS Y=2.5\r", ACK),
            (b"JS Y?\r", b":A JS_SLOW=2.500000\r\n"),
        ],
        id="tv058_joystick_speeds",
    ),
    pytest.param(
        [
            (b"RS X\r", b":A 10\r\n"),
            (b"RS X Y\r", b":A 10 10\r\n"),
            (b"RS X?\r", b":A N\r\n"),
            (b"RS X-\r", b":A  \r\n"),
            (b"RS X+\r", b":A  \r\n"),
        ],
        id="tv062_rdstat_forms",
    ),
    pytest.param(
        [(b"RB X\r", b":A\x0a\r\n"), (b"RB Y X\r", b":A\x0a\x0a\r\n")],
        id="tv063_rdsbyte_raw",
        marks=pytest.mark.smoke,
    ),
    pytest.param(
        [(b"LL X? Y? Z?\r", b":A X=24 Y=25 Z=26\r\n"), (b"LL X=0\r", b":N-4\r\n")], id="tv111_low_level_ids"
    ),
    pytest.param(
        [(b"Z2B Y?\r", b":A Y=1\r\n"), (b"Z2B Z?\r", b":A Z=2\r\n"), (b"Z2B Z=200\r", b":N-4\r\n")],
        id="tv112_hardware_index",
    ),
    pytest.param(
        [(b"RA X Y\r", b":A 128 128\r\n"), (b"RA T\r", b":N-2\r\n"), (b"RA Z F\r", b":A 0 0\r\n")],
        id="tv114_adc",
    ),
]


@pytest.mark.parametrize("steps", VECTORS)
def test_tv_exchanges(ms: Host, steps: Sequence[Step]) -> None:
    """Each case is one test vector on the default profile, every reply byte for byte (MS-17,
    MS-22, MS-35, MS-48, MS-54, MS-55, MS-59, MS-60, MS-73, MS-74, MS-79, MS-81, MS-82, MS-97,
    MS-114, MS-115, MS-117)."""
    ms.run(steps)


KNOB_VECTORS = [
    pytest.param({"ack_trailing_space": True}, [(b"S X=4.69\r", b":A \r\n")], id="tv012_ack_trailing_space"),
    pytest.param(
        {"reply_shape_overrides": {"OS": "colon_axis_A"}},
        [(b"OS X=.05\r", ACK), (b"OS X?\r", b":X=0.049982 A\r\n")],
        id="tv039_overshoot_colon_shape",
    ),
    pytest.param(
        {"reply_shape_overrides": {"PC": "colon_axis_A"}},
        [(b"PC X?\r", b":X=0.000022 A\r\n")],
        id="tv042_finish_error_colon_shape",
    ),
    pytest.param(
        {"reply_trailing_space": True},
        [(b"S X?\r", b":A X=5.145600 \r\n"), (b"W X\r", b":A 0 \r\n"), (b"/\r", b"N\r\n")],
        id="tv043_reply_trailing_space",
    ),
    pytest.param({"rb_space_after_ack": True}, [(b"RB X\r", b":A \x0a\r\n")], id="tv064_rdsbyte_space"),
]


@pytest.mark.parametrize(("knobs", "steps"), KNOB_VECTORS)
def test_tv_knob_exchanges(
    connect: Callable[..., Host], knobs: dict[str, Any], steps: Sequence[Step]
) -> None:
    """Vectors of the other reading of a [conflict] or [choice] rule, selected by a knob (MS-17,
    MS-36, MS-37, MS-38, MS-82)."""
    connect(overrides={"knobs": knobs}).run(steps)
