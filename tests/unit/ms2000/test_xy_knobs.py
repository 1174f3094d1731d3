"""XY KNOBS (§9.15): the knob speeds and knob `knob_speeds_need_module`, beyond TV-211
(tests/conformance/ms2000)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from emulator.device import ControlError
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(ALL_MODULES)


def test_slow_mode_uses_the_slow_speed(ms: Harness) -> None:
    """MS-KNOB-1: the joystick button's toggle selects the knob speed too: slow is F."""
    ms.input("button", name="joystick", ms=100)
    ms.wait(0.5)
    ms.input("xy_knob", x_counts=100, y_counts=-50)
    ms.wait(1)
    assert ms.cmd("W X Y") == b":A 100 -50\r\n"


def test_speed_follows_js_f_and_t(ms: Harness) -> None:
    """MS-KNOB-1: fast speed F × T³ (2 × 3³ = 54)."""
    assert ms.cmd("JS F=2 T=3") == ACK
    ms.input("xy_knob", y_counts=10)
    ms.wait(1)
    assert ms.cmd("W Y") == b":A 540\r\n"


def test_knob_motion_is_manual(ms: Harness) -> None:
    """MS-KNOB-2, MS-78, MS-51: not busy; the MOVREL target follows the knob."""
    ms.input("xy_knob", x_counts=1000)
    assert ms.cmd("/") == b"N\r\n"
    ms.wait(2)
    assert ms.cmd("R X=100") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 64100\r\n"


def test_disabled_manual_input_ignores_the_knob(ms: Harness) -> None:
    """MS-73: `J X-` turns the manual inputs of X off, knobs included [choice]."""
    ms.cmd("J X-")
    ms.input("xy_knob", x_counts=100)
    ms.wait(1)
    assert ms.cmd("W X") == b":A 0\r\n"


def test_bad_input_is_refused(ms: Harness) -> None:
    with pytest.raises(ControlError, match="x_counts"):
        ms.input("xy_knob", x_counts="many")
    with pytest.raises(ControlError, match="unknown"):
        ms.input("xy_knob", z_counts=1)


def test_js_f_t_answer_without_the_module_by_default(make: Callable[..., Harness]) -> None:
    """MS-74 [doc]: `JS F`/`JS T` are letters of the base `JS`; P0 (no XY KNOBS) answers them and
    has no knob input (MS-118)."""
    p0 = make()
    assert p0.cmd("JS F? T?") == b":A KNOB_SLOW=1.000000 KNOB_MULT=4\r\n"
    assert p0.cmd("JS F=2") == ACK
    with pytest.raises(ControlError, match="xy_knob"):
        p0.input("xy_knob", x_counts=1)


def test_knob_makes_js_f_t_need_the_module(make: Callable[..., Harness]) -> None:
    """Knob `knob_speeds_need_module` (MS-KNOB-1, MS-30): the other reading, `JS F/T` only in XY
    KNOBS builds; `JS X/Y/Z` unaffected."""
    knob = {"knobs": {"knob_speeds_need_module": True}}
    p0 = make(overrides=knob)
    assert p0.cmd("JS F?") == b":N-2\r\n"
    assert p0.cmd("JS T=3") == b":N-2\r\n"
    assert p0.cmd("JS X?") == b":A JS_FAST=100\r\n"
    with_knobs = make(ALL_MODULES, knob)
    assert with_knobs.cmd("JS F? T?") == b":A KNOB_SLOW=1.000000 KNOB_MULT=4\r\n"
