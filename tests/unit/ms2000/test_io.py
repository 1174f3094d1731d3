"""Status reads, manual inputs, buttons, TTL and unsolicited output (§6.5…§6.7) on the model, beyond
the test vectors, which run in tests/conformance/ms2000 (TV-62…TV-64, TV-70…TV-89, TV-114)."""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.interpreter import PARSED_LINES
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def test_joystick_respects_limits_and_resets_target_ms83_ms51(ms: Harness) -> None:
    ms.cmd("SU X=1")
    ms.input("joystick", x=0.5, y=0)
    ms.wait(2.0)
    assert ms.cmd("W X") == b":A 10000\r\n"
    ms.input("joystick", x=0, y=0)
    ms.cmd("R X=-10")
    ms.idle()
    assert ms.get("axes")["X"]["machine_counts"] == 45396 - 45


def test_joystick_dead_band_and_dip_inversion_ms83(ms: Harness) -> None:
    ms.input("joystick", x=0.01, y=0)
    ms.wait(1.0)
    assert ms.cmd("W X") == b":A 0\r\n"
    ms.input("dip", sw8="down")
    ms.input("joystick", x=1.0, y=0)
    ms.wait(0.1)
    assert int(ms.cmd("W X")[3:]) < 0


def test_button_functions_and_assignment_ms86(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.cmd("BE F=1") == ACK
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("BE F=7") == b":N-4\r\n"
    assert ms.cmd("BE M=0") == ACK
    assert ms.cmd("BE R? T? M?") == b":A T=0 R=2 M=0\r\n"
    ms.cmd("M X=1000")
    ms.idle()
    ms.input("button", name="zero", ms=200)
    ms.wait(0.3)
    assert ms.cmd("W X") == b":A 1000\r\n"
    assert ms.cmd("BCA F=1") == ACK
    ms.input("button", name="home", ms=5000)
    ms.wait(5.1)
    assert ms.cmd("W X") == b":A 1000\r\n"


def _pulse_and_read_z(ms: Harness) -> bytes:
    ms.input("ttl_in0", pulse_ms=1)
    ms.wait(0.1)
    return ms.cmd("W Z")


def test_z_stack_triangle_ms94(ms: Harness) -> None:
    ms.cmd("ZS X=10 Y=2 Z=1")
    ms.cmd("TTL X=4")
    got = [_pulse_and_read_z(ms) for _ in range(6)]
    assert got == [f":A {n}\r\n".encode() for n in (10, 20, 10, 0, 10, 20)]
    assert ms.cmd("ZS X? Y? Z? F?") == b":A X=10.000000 Y=2 Z=1 F=500\r\n"


def test_ttl_inputs_disabled_by_button_enable_ms86(ms: Harness) -> None:
    ms.cmd("TTL X=10")
    ms.cmd("BE Z=15")
    ms.input("ttl_in0", pulse_ms=1)
    assert ms.get("ttl_out0") == 0


def test_vb_positions_after_move_and_button_notice_ms96(ms: Harness) -> None:
    ms.cmd("VB X=34")
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.output() == b":A 1000 0 0\r\n"
    ms.input("button", name="joystick", ms=1500)
    ms.wait(1.6)
    assert ms.output() == b"P\r\n"


@pytest.mark.parametrize(
    ("name", "params"), [("joystick", {"x": 2}), ("button", {"name": "foo"}), ("limit", {"axis": "Q"})]
)
def test_bad_control_input_is_a_clear_error(ms: Harness, name: str, params: dict[str, object]) -> None:
    from emulator.device import ControlError

    with pytest.raises(ControlError):
        ms.input(name, **params)


def test_a_line_parsed_once_answers_the_same_every_time(ms: Harness) -> None:
    """Parsed lines are remembered (hosts poll the same few lines): a repeated line, a blank line
    and an unknown word answer as the first time, and the memory stays bounded."""
    for _ in range(3):
        assert ms.cmd("W X Y") == b":A 0 0\r\n"
        assert ms.cmd("") == b":N-1\r\n"
        assert ms.cmd("FOO") == b":N-1\r\n"
        assert ms.cmd("S X=1") == b":A\r\n"
        assert ms.cmd("S X?") == b":A X=1.000000\r\n"
    for n in range(PARSED_LINES + 10):
        ms.cmd(f"W X{' ' * (n % 7)} Y{' ' * (n // 7)}")
    assert len(ms.dev.interpreter._parsed) <= PARSED_LINES
