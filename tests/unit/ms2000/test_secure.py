"""SOL_LK and U_SERVO_LK (§9.17): OUT0 mode 9, the auto-lock timer and the rest of MS-SECURE-1 beyond
TV-216 and TV-217 (tests/conformance/ms2000)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(ALL_MODULES)


def test_solenoid_settings_and_ranges(ms: Harness) -> None:
    """MS-SECURE-1: factory X 0 and F 5; Y/Z 0–99 %, F 0–255 min, T 0–65000 ms; X only 0 or 1."""
    assert ms.cmd("SECURE X? F?") == b"X=0 F=5 :A\r\n"
    assert ms.cmd("SECURE Y=80 Z=20 T=100") == ACK
    assert ms.cmd("SECURE Y? Z? T?") == b"Y=80 Z=20 T=100 :A\r\n"
    assert ms.cmd("SECURE Y=100") == b":N-4\r\n"
    assert ms.cmd("SECURE F=256") == b":N-4\r\n"
    assert ms.cmd("SECURE X=2") == b":N-4\r\n"
    assert ms.get("secure")["locked"] is True


def test_solenoid_drives_out0_in_mode_9(ms: Harness) -> None:
    """MS-SECURE-1, MS-91 [choice]: in `TTL Y=9` OUT0 is high while unlocked, at the pull-in power
    for T ms and then at the hold power."""
    assert ms.cmd("SECURE Y=90 Z=25 T=200") == ACK
    assert ms.cmd("SECURE X=1") == ACK
    assert ms.get("ttl_out0") == 0  # mode 0: the output is not the lock's
    assert ms.cmd("TTL Y=9") == ACK
    assert ms.get("ttl_out0") == 1
    assert ms.get("ttl_out0_pwm") == 90
    ms.wait(0.3)
    assert ms.get("ttl_out0_pwm") == 25
    assert ms.cmd("SECURE X=0") == ACK
    assert ms.get("ttl_out0") == 0
    assert ms.get("ttl_out0_pwm") == 0


def test_auto_lock_after_f_minutes(ms: Harness) -> None:
    """MS-SECURE-1: the auto-lock timer locks again F minutes after an unlock; F=0 never."""
    assert ms.cmd("SECURE F=1 X=1") == ACK
    ms.wait(59)
    assert ms.get("secure")["locked"] is False
    ms.wait(2)
    assert ms.get("secure")["locked"] is True
    assert ms.cmd("SECURE F=0 X=1") == ACK
    ms.wait(600)
    assert ms.get("secure")["locked"] is False


def test_lcd_segment_and_reset(make: Callable[..., Harness]) -> None:
    """§9.0 [choice]: LCD segment `LCK`/`OPN`; a reset locks again (settings are volatile). (With
    every module of ms2000-all-modules line 2 is cut at 20 characters before this segment.)"""
    ms = make(ALL_MODULES, {"modules": ["LL COMMANDS", "SOL_LK"]})
    assert "LCK" in ms.get("lcd")[1]
    ms.cmd("SECURE X=1")
    assert "OPN" in ms.get("lcd")[1]
    ms.cmd("~")
    assert ms.cmd("SECURE X?") == b"X=0 :A\r\n"


def test_micro_servo_range_and_output(make: Callable[..., Harness]) -> None:
    """MS-SECURE-1, MS-91 [choice]: 0.0–1.0; in `TTL Y=9` the lever position is the PWM duty."""
    ms = make("ms2000-uservo")
    assert ms.cmd("SECURE X=1.5") == b":N-4\r\n"
    assert ms.cmd("TTL Y=9") == ACK
    assert ms.cmd("SECURE X=0.5") == ACK
    assert ms.get("ttl_out0_pwm") == 50
    assert ms.cmd("SECURE X=0") == ACK
    assert ms.get("secure")["locked"] is True
    assert ms.cmd("BU X").rstrip(b"\r\n").split(b"\r")[-2:] == [b"LL COMMANDS", b"U_SERVO_LK"]


def test_without_the_module(make: Callable[..., Harness]) -> None:
    """MS-118: P0 has neither insert."""
    assert make().cmd("SECURE X=1") == b":N-1\r\n"
