"""Status reads, manual inputs, buttons, TTL and unsolicited output (§6.5…§6.7): TV-62…TV-64,
TV-70…TV-89, TV-114."""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.interpreter import PARSED_LINES
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def test_tv_062_status_reads_ms81_ms79_ms35(ms: Harness) -> None:
    assert ms.cmd("RS X") == b":A 10\r\n"
    assert ms.cmd("RS X Y") == b":A 10 10\r\n"
    assert ms.cmd("RS X?") == b":A N\r\n"
    assert ms.cmd("RS X-") == b":A  \r\n"
    assert ms.cmd("RS X+") == b":A  \r\n"


def test_tv_063_raw_status_byte_ms82(ms: Harness) -> None:
    assert ms.cmd("RB X") == b":A\x0a\r\n"
    assert ms.cmd("RB Y X") == b":A\x0a\x0a\r\n"


def test_tv_064_raw_status_space_ms82(make: type[Harness]) -> None:
    assert make(overrides={"knobs": {"rb_space_after_ack": True}}).cmd("RB X") == b":A \x0a\r\n"


def test_tv_070_joystick_is_not_busy_ms83_ms117(ms: Harness) -> None:
    ms.input("joystick", x=1.0, y=0)
    assert ms.cmd("/") == b"N\r\n"
    assert ms.cmd("RA X Y") == b":A 255 128\r\n"
    ms.wait(1.0)
    ms.input("joystick", x=0, y=0)
    reply = ms.cmd("W X")
    assert 76000 <= int(reply[3:]) <= 77600


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


def test_tv_071_wheel_ms84(ms: Harness) -> None:
    ms.input("wheel", counts=100)
    ms.wait(0.5)
    assert ms.cmd("W Z") == b":A 500\r\n"
    assert ms.cmd("/") == b"N\r\n"


def test_tv_072_zero_button_and_flag_byte_ms85_ms86(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    ms.input("button", name="zero", ms=200)
    ms.wait(0.3)
    assert ms.cmd("W X Y Z") == b":A 0 0 0\r\n"
    assert ms.cmd("EXTRA M?") == b":A 64\r\n"
    assert ms.cmd("EXTRA M?") == b":A 0\r\n"


def test_tv_073_disabled_button_ms86(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.cmd("BE X?") == b":A X=31\r\n"
    assert ms.cmd("BE Z=12") == ACK
    ms.input("button", name="zero", ms=200)
    ms.wait(0.3)
    assert ms.cmd("W X") == b":A 1000\r\n"


def test_tv_074_flag_byte_runs_presses_ms86_ms85(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.cmd("EXTRA M=4") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("EXTRA M?") == b":A 4\r\n"


def test_tv_075_joystick_speed_toggle_char_ms85_ms81(ms: Harness) -> None:
    ms.input("button", name="joystick", ms=200)
    ms.wait(0.3)
    assert ms.cmd("RS X-") == b":A s\r\n"
    ms.input("button", name="joystick", ms=200)
    ms.wait(0.3)
    assert ms.cmd("RS X-") == b":A f\r\n"
    ms.wait(1.0)
    assert ms.cmd("RS X-") == b":A  \r\n"


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


def test_tv_076_ttl_settings_and_toggle_mode_ms89_ms90(ms: Harness) -> None:
    assert ms.cmd("TTL X? Y? Z? F?") == b":A X=0 Y=0 Z=0 F=1\r\n"
    assert ms.cmd("TTL X=10") == ACK
    assert ms.cmd("TTL X?") == b":A X=10\r\n"
    ms.input("ttl_in0", pulse_ms=1)
    assert ms.get("ttl_out0") == 1


def test_tv_077_modes_of_absent_modules_ms90_ms118(ms: Harness) -> None:
    assert ms.cmd("TTL X=7") == b":N-4\r\n"
    assert ms.cmd("TTL X=11") == b":N-4\r\n"
    assert ms.cmd("TTL X=3") == b":N-4\r\n"


def test_tv_078_end_of_move_pulse_ms91_ms93(ms: Harness) -> None:
    assert ms.cmd("TTL Y=2") == ACK
    assert ms.cmd("RT Y=5") == ACK
    ms.cmd("M X=1000")
    ms.idle()
    ms.wait(0.01)
    rise, fall = ms.take_events("ttl_out0")
    assert (rise["level"], fall["level"]) == (1, 0)
    assert abs(fall["t"] - rise["t"] - 0.005) < 1e-9
    landed = ms.take_events("move_complete")[0]["t"]
    assert rise["t"] == landed


def test_tv_079_out_modes_and_polarity_ms91(ms: Harness) -> None:
    assert ms.cmd("TTL Y=3") == b":N-4\r\n"
    assert ms.cmd("TTL F=-1") == ACK
    assert ms.get("ttl_out0") == 1
    assert ms.cmd("TTL F=2") == b":N-4\r\n"
    assert ms.cmd("TTL Y=1 F=1") == ACK
    assert ms.get("ttl_out0") == 1


def test_tv_080_bare_ttl_reads_in0_inverted_ms92(ms: Harness) -> None:
    assert ms.cmd("TTL") == b":A 1\r\n"
    ms.input("ttl_in0", level=1)
    assert ms.cmd("TTL") == b":A 0\r\n"


def test_tv_081_rtime_ms93(ms: Harness) -> None:
    assert ms.cmd("RT Y?") == b":A Y=10.000000\r\n"
    assert ms.cmd("RT X=10") == b":N-4\r\n"
    assert ms.cmd("RT X?") == b":A X=200.000000\r\n"


def _pulse_and_read_z(ms: Harness) -> bytes:
    ms.input("ttl_in0", pulse_ms=1)
    ms.wait(0.1)
    return ms.cmd("W Z")


def test_tv_082_z_stack_sawtooth_ms94_ms90(ms: Harness) -> None:
    assert ms.cmd("ZS X=10 Y=3 Z=0 F=500") == ACK
    assert ms.cmd("TTL X=4") == ACK
    assert [_pulse_and_read_z(ms) for _ in range(4)] == [
        b":A 10\r\n",
        b":A 20\r\n",
        b":A 30\r\n",
        b":A 0\r\n",
    ]


def test_tv_083_z_stack_timeout_restarts_ms94(ms: Harness) -> None:
    ms.cmd("ZS X=10 Y=3 Z=0 F=500")
    ms.cmd("TTL X=4")
    _pulse_and_read_z(ms)
    assert _pulse_and_read_z(ms) == b":A 20\r\n"
    ms.wait(0.6)
    assert _pulse_and_read_z(ms) == b":A 0\r\n"
    assert _pulse_and_read_z(ms) == b":A 10\r\n"


def test_z_stack_triangle_ms94(ms: Harness) -> None:
    ms.cmd("ZS X=10 Y=2 Z=1")
    ms.cmd("TTL X=4")
    got = [_pulse_and_read_z(ms) for _ in range(6)]
    assert got == [f":A {n}\r\n".encode() for n in (10, 20, 10, 0, 10, 20)]
    assert ms.cmd("ZS X? Y? Z? F?") == b":A X=10.000000 Y=2 Z=1 F=500\r\n"


def test_tv_084_repeat_relative_move_ms90(ms: Harness) -> None:
    ms.cmd("R X=100")
    ms.idle()
    assert ms.cmd("TTL X=2") == ACK
    ms.input("ttl_in0", pulse_ms=1)
    ms.idle()
    assert ms.cmd("W X") == b":A 200\r\n"


def test_tv_085_position_reports_ms90_ms18(ms: Harness) -> None:
    assert ms.cmd("TTL X=5") == ACK
    assert ms.cmd("RT X=100") == ACK
    ms.input("ttl_in0", pulse_ms=1)
    ms.wait(0.25)
    assert ms.output() == b"100 0 0\r\n200 0 0\r\n"
    ms.input("ttl_in0", pulse_ms=1)
    ms.wait(0.5)
    assert ms.output() == b""


def test_ttl_inputs_disabled_by_button_enable_ms86(ms: Harness) -> None:
    ms.cmd("TTL X=10")
    ms.cmd("BE Z=15")
    ms.input("ttl_in0", pulse_ms=1)
    assert ms.get("ttl_out0") == 0


def test_tv_086_ensync_ms95(ms: Harness) -> None:
    assert ms.cmd("ES X=0.5") == ACK
    assert ms.get("ensync_out") == 0
    ms.cmd("M X=10000")
    ms.idle()
    assert ms.get("ensync_out") == 1
    assert ms.cmd("ES Z=1") == b":N-2\r\n"
    assert ms.cmd("ES X?") == b":A X=0.500000\r\n"
    ms.cmd("M X=0")
    ms.idle()
    assert ms.get("ensync_out") == 0


def test_tv_087_move_done_notice_ms96_ms18(ms: Harness) -> None:
    assert ms.cmd("VB X=1") == ACK
    assert ms.cmd("M X=100") == ACK
    ms.idle()
    assert ms.output() == b"N\r\n"


def test_tv_088_move_reply_lists_targets_ms96(ms: Harness) -> None:
    assert ms.cmd("VB X=16") == ACK
    assert ms.cmd("M X=1000 Y=-505") == b":A 1000 -505\r\n"


def test_tv_089_in1_edges_ms96(ms: Harness) -> None:
    assert ms.cmd("VB X=4") == ACK
    ms.input("ttl_in1", level=1)
    assert ms.output() == b"H\r\n"
    ms.input("ttl_in1", level=0)
    assert ms.output() == b"L\r\n"


def test_vb_positions_after_move_and_button_notice_ms96(ms: Harness) -> None:
    ms.cmd("VB X=34")
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.output() == b":A 1000 0 0\r\n"
    ms.input("button", name="joystick", ms=1500)
    ms.wait(1.6)
    assert ms.output() == b"P\r\n"


def test_tv_114_adc_reads_ms117(ms: Harness) -> None:
    assert ms.cmd("RA X Y") == b":A 128 128\r\n"
    assert ms.cmd("RA T") == b":N-2\r\n"
    assert ms.cmd("RA Z F") == b":A 0 0\r\n"


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
