"""Settings commands, argument grammar on the wire, reply shapes and errors (§2.4, §3, §4, §6.8):
TV-11…TV-25, TV-39…TV-46, TV-57, TV-58, TV-91, TV-111, TV-112, TV-114."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def test_tv_011_speed_read_back_ms17_ms54_ms35(ms: Harness) -> None:
    assert ms.cmd("S X=4.69") == ACK
    assert ms.cmd("S X?") == b":A X=4.690000\r\n"


def test_tv_012_ack_trailing_space_ms17(make: Callable[..., Harness]) -> None:
    assert make(overrides={"knobs": {"ack_trailing_space": True}}).cmd("S X=4.69") == b":A \r\n"


def test_tv_013_prefixed_items_and_reply_order_ms22_ms29_ms21(ms: Harness) -> None:
    assert ms.cmd("S VX=4.690000 VY=4.690000 ") == ACK
    assert ms.cmd("S Y? X?") == b":A X=4.690000 Y=4.690000\r\n"


def test_tv_014_prefixed_accel_ms22_ms55(ms: Harness) -> None:
    assert ms.cmd("AC ACX=25.000000 ") == ACK
    assert ms.cmd("AC X? Y?") == b":X=25 Y=70 A\r\n"


def test_tv_015_spaces_around_equals_ms23(ms: Harness) -> None:
    assert ms.cmd("S Y = 0.5") == ACK
    assert ms.cmd("S Y?") == b":A Y=0.500000\r\n"


def test_tv_018_speed_clamped_to_maximum_ms54(ms: Harness) -> None:
    assert ms.cmd("S X=10000") == ACK
    assert ms.cmd("S X?") == b":A X=7.680000\r\n"
    assert ms.cmd("S Z=99") == ACK
    assert ms.cmd("S Z?") == b":A Z=1.920000\r\n"


def test_tv_019_default_speed_and_zero_refused_ms54(ms: Harness) -> None:
    assert ms.cmd("S Z?") == b":A Z=1.286400\r\n"
    assert ms.cmd("S X=0") == b":N-4\r\n"


def test_tv_020_six_decimal_rounding_ms48(ms: Harness) -> None:
    assert ms.cmd("S X=1.23456789") == ACK
    assert ms.cmd("S X?") == b":A X=1.234568\r\n"


def test_tv_021_letters_a_command_does_not_accept_ms42_ms30(ms: Harness) -> None:
    assert ms.cmd("S F?") == b":N-2\r\n"
    assert ms.cmd("TTL Q=1") == b":N-2\r\n"
    assert ms.cmd("TTL R?") == b":N-2\r\n"


def test_tv_022_lowest_error_wins_nothing_applied_ms40_ms27(ms: Harness) -> None:
    assert ms.cmd("S Q=0") == b":N-2\r\n"
    assert ms.cmd("S X=1 Y=0") == b":N-4\r\n"
    assert ms.cmd("S X?") == b":A X=5.145600\r\n"


def test_tv_023_last_item_wins_ms27(ms: Harness) -> None:
    assert ms.cmd("S X=1 X=2") == ACK
    assert ms.cmd("S X?") == b":A X=2.000000\r\n"


def test_tv_024_where_errors_ms30_ms31_ms77(ms: Harness) -> None:
    assert ms.cmd("W Q") == b":N-2\r\n"
    assert ms.cmd("W") == b":N-3\r\n"
    assert ms.cmd("M X=1000 Q=5") == b":N-2\r\n"
    assert ms.cmd("W X") == b":A 0\r\n"


def test_tv_025_mixed_set_and_query_ms28_ms65(ms: Harness) -> None:
    assert ms.cmd("SL X=-50 Y=-50 Z?") == b":A Z=-110.000\r\n"
    assert ms.cmd("SL X? Y?") == b":A X=-50.000 Y=-50.000\r\n"


def test_malformed_item_is_undefined_error_ms39(ms: Harness) -> None:
    assert ms.cmd("S 5=3") == b":N-6\r\n"
    assert ms.cmd("S 5=3 Q=1") == b":N-2\r\n"


@pytest.mark.parametrize("word", ["S", "B", "M", "R", "!", "SS", "AC", "LD", "I", "AZ", "RS"])
def test_commands_needing_items_ms31(ms: Harness, word: str) -> None:
    assert ms.cmd(word) == b":N-3\r\n"


@pytest.mark.parametrize("word", ["Z", "V", "CD", "N", "BU", "DU", "TTL", "LCD", "UN", "/", "RM"])
def test_bare_forms_with_their_own_meaning_ms31(ms: Harness, word: str) -> None:
    assert not ms.cmd(word).startswith(b":N")


def test_tv_039_overshoot_documented_shape_ms36_ms38(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"reply_shape_overrides": {"OS": "colon_axis_A"}}})
    assert h.cmd("OS X=.05") == ACK
    assert h.cmd("OS X?") == b":X=0.049982 A\r\n"


def test_tv_040_drift_error_ms59(ms: Harness) -> None:
    assert ms.cmd("E X=.0004") == ACK
    assert ms.cmd("E X?") == b":X=0.000400 A\r\n"
    assert ms.cmd("E X=0") == ACK
    assert ms.cmd("E X?") == b":X=0.000400 A\r\n"


def test_tv_041_finish_error_ms60_ms37_ms22(ms: Harness) -> None:
    assert ms.cmd("PC X?") == b":A X=0.000022\r\n"
    assert ms.cmd("PC PCX=0.000001 ") == ACK
    assert ms.cmd("PC X?") == b":A X=0.000001\r\n"


def test_tv_042_finish_error_other_shape_ms37(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"reply_shape_overrides": {"PC": "colon_axis_A"}}})
    assert h.cmd("PC X?") == b":X=0.000022 A\r\n"


def test_tv_043_reply_trailing_space_ms38(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"reply_trailing_space": True}})
    assert h.cmd("S X?") == b":A X=5.145600 \r\n"
    assert h.cmd("W X") == b":A 0 \r\n"
    assert h.cmd("/") == b"N\r\n"


def test_tv_044_accel_ms55_ms35(ms: Harness) -> None:
    assert ms.cmd("AC X=50 Y=50 Z=50") == ACK
    assert ms.cmd("AC X? Y? Z?") == b":X=50 Y=50 Z=50 A\r\n"
    assert ms.cmd("AC X=0") == b":N-4\r\n"


def test_tv_046_stored_servo_settings_ms97(ms: Harness) -> None:
    assert ms.cmd("AA X? Y? Z?") == b":A X=83 Y=78 Z=59\r\n"
    assert ms.cmd("KV Z?") == b":A Z=39\r\n"
    assert ms.cmd("KA Z?") == b":A Z=0\r\n"
    assert ms.cmd("D X?") == b":A X=0.055000\r\n"
    assert ms.cmd("KP X?") == b":A X=100\r\n"
    assert ms.cmd("EP X=2") == b":N-4\r\n"


def test_tv_057_joystick_device_and_enable_ms73_ms79(ms: Harness) -> None:
    assert ms.cmd("J X?") == b":A X=2\r\n"
    assert ms.cmd("J X-") == ACK
    assert ms.cmd("RS X") == b":A 2\r\n"
    assert ms.cmd("J X=5") == b":N-4\r\n"


def test_tv_058_joystick_speeds_named_ms74_ms35(ms: Harness) -> None:
    assert ms.cmd("JS X? Y?") == b":A JS_FAST=100 JS_SLOW=5\r\n"
    assert ms.cmd("JS X=0") == b":N-4\r\n"
    assert ms.cmd("JS Y=-50") == ACK
    assert (
        ms.cmd("JS Y? Z? F? T?") == b":A JS_SLOW=-50 JS_WHEEL=100.000000 KNOB_SLOW=1.000000 KNOB_MULT=4\r\n"
    )
    assert ms.cmd("JS Y=2.5") == ACK
    assert ms.cmd("JS Y?") == b":A JS_SLOW=2.500000\r\n"


def test_tv_091_vb_read_only_and_module_letter_ms109(ms: Harness) -> None:
    assert ms.cmd("VB Y?") == b":A Y=0\r\n"
    assert ms.cmd("VB Y=1") == b":N-4\r\n"
    assert ms.cmd("VB T=1027") == b":N-2\r\n"
    ms.input("ttl_in1", level=1)
    assert ms.cmd("VB Y?") == b":A Y=1\r\n"


def test_vb_silent_ms109(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"vb_silent": True}})
    assert h.cmd("VB Z=1") == b""
    assert h.cmd("VB Z?") == b":A Z=1\r\n"


def test_tv_111_low_level_ids_ms114(ms: Harness) -> None:
    assert ms.cmd("LL X? Y? Z?") == b":A X=24 Y=25 Z=26\r\n"
    assert ms.cmd("LL X=0") == b":N-4\r\n"


def test_tv_112_axis_index_ms115(ms: Harness) -> None:
    assert ms.cmd("Z2B Y?") == b":A Y=1\r\n"
    assert ms.cmd("Z2B Z?") == b":A Z=2\r\n"
    assert ms.cmd("Z2B Z=200") == b":N-4\r\n"


def test_z2b_renames_after_save_and_reset_ms115(ms: Harness) -> None:
    assert ms.cmd("Z2B Z=70") == ACK
    assert ms.cmd("Z2B Y=88") == b":N-4\r\n"
    ms.cmd("SS Z")
    ms.cmd("~")
    assert ms.cmd("W F") == b":A 0\r\n"
    assert ms.cmd("W Z") == b":N-2\r\n"
    assert b"Motor Axes: X Y F\r" in ms.cmd("BU X")


def test_other_stored_settings_read_back_ms97_ms61_ms62(ms: Harness) -> None:
    for command, reply in [
        ("MA X=2", ACK),
        ("MA X?", b":A X=2\r\n"),
        ("RU X=2.5", ACK),
        ("RU X?", b":A X=2.500000\r\n"),
        ("C X?", b":A X=45396.000000\r\n"),
        ("CCA X=5 Y=2 Z=3", ACK),
        ("CCA X? Y? Z?", b":A X=5 Y=2 Z=3\r\n"),
        ("UM Y?", b":A Y=10000.000000\r\n"),
        ("WT X=5 Y=6", ACK),
        ("WT Y? X?", b":X=5 Y=6 A\r\n"),
        ("B Z?", b":Z=0.010000 A\r\n"),
    ]:
        assert ms.cmd(command) == reply, command
