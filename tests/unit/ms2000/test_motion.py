"""Units, moves, limits, home, spin, vector, halt, drift and runaway (§5, §6.1…§6.4): TV-26…TV-38,
TV-45, TV-47…TV-56, TV-59…TV-61, TV-65…TV-69."""

from __future__ import annotations

import itertools
import math

import pytest

from emulator.devices.ms2000.trajectory import plan
from emulator.motion import Trapezoid
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def at(ms: Harness, x: int) -> None:
    assert ms.cmd(f"M X={x}") == ACK
    ms.idle()


def test_tv_026_move_and_where_in_hardware_order_ms51_ms77_ms29_ms47(ms: Harness) -> None:
    assert ms.cmd("M X=1000 Y=-505") == ACK
    ms.idle()
    assert ms.cmd("W Z X Y") == b":A 1000 -505 0\r\n"


def test_tv_027_where_decimals_show_quantisation_ms109_ms47_ms45_ms46(ms: Harness) -> None:
    ms.cmd("M X=1000 Y=-505")
    ms.idle()
    assert ms.cmd("VB Z=1") == ACK
    assert ms.cmd("W X") == b":A 1000.1\r\n"
    assert ms.cmd("VB Z=3") == ACK
    assert ms.cmd("W X Y") == b":A 1000.088 -504.890\r\n"


def test_tv_028_targets_quantised_to_counts_ms45_ms43(ms: Harness) -> None:
    at(ms, 12345)
    assert ms.cmd("W X") == b":A 12345\r\n"
    assert ms.get("axes")["X"]["machine_counts"] == 56041


def test_tv_029_relative_moves_accumulate_quantisation_ms45_ms51(ms: Harness) -> None:
    for _ in range(3):
        assert ms.cmd("R X=10") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 30\r\n"
    assert ms.get("axes")["X"]["target_counts"] == 135


def test_tv_030_missing_value_is_zero_ms25(ms: Harness) -> None:
    at(ms, 1000)
    assert ms.cmd("M X Y") == ACK
    ms.idle()
    assert ms.cmd("W X Y") == b":A 0 0\r\n"
    assert ms.cmd("M X=") == ACK
    assert ms.cmd("M X=abc") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 0\r\n"


def test_tv_031_number_forms_ms26(ms: Harness) -> None:
    at(ms, 0)
    assert ms.cmd("M X=1e3") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 1000\r\n"
    assert ms.cmd("M X=.5e1") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 5\r\n"


def test_tv_032_negative_unit_multiplier_ms44_ms43_ms46(ms: Harness) -> None:
    assert ms.cmd("UM X?") == b":A X=10000.000000\r\n"
    assert ms.cmd("UM X=-10000 Y=10000") == ACK
    assert ms.cmd("M X=1000") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 1000\r\n"
    assert ms.get("axes")["X"]["machine_counts"] == -4540
    assert ms.cmd("UM X=0") == b":N-4\r\n"


def test_tv_033_trapezoid_duration_ms52_ms53_ms32(ms: Harness) -> None:
    for command in ("S X=1", "AC X=100", "B X=0"):
        assert ms.cmd(command) == ACK
    assert ms.cmd("M X=100000") == ACK
    ms.wait(10.0)
    assert ms.cmd("/") == b"B\r\n"
    ms.wait(0.2)
    assert ms.cmd("/") == b"N\r\n"


def test_duration_matches_motion_trapezoid_ms52(ms: Harness) -> None:
    ms.cmd("B X=0")
    ms.cmd("M X=20000")
    took = ms.idle(step=0.001)
    expected = Trapezoid(2.0, 5.1456, 0.07).duration
    assert abs(took - expected) < 0.002


@pytest.mark.parametrize(("bit5_up", "ramp_up", "ramp_down"), [(True, 63, 31), (False, 31, 63)])
def test_tv_034_tv35_status_bits_while_moving_ms79_ms80(
    make: type[Harness], bit5_up: bool, ramp_up: int, ramp_down: int
) -> None:
    h = make(overrides={"knobs": {"status_bit5_up_is_one": bit5_up}})
    h.cmd("S X=1")
    h.cmd("AC X=1000")
    h.cmd("M X=100000")
    h.wait(0.5)
    assert h.cmd("RS X") == f":A {ramp_up}\r\n".encode()
    h.wait(4.5)
    assert h.cmd("RS X") == b":A 15\r\n"
    h.wait(5.5)
    assert h.cmd("RS X") == f":A {ramp_down}\r\n".encode()


def test_tv_036_new_target_replans_from_motion_ms63(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.5)
    assert ms.cmd("M X=0") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.get("axes")["X"]["max_user_mm"] < 10


def test_replanning_keeps_velocity_continuous_ms63() -> None:
    segments = plan(0.0, 0.0, 100.0, -50.0, 200.0, 1000.0)
    assert segments[0].a < 0 and segments[0].v0 == 100.0
    for before, after in itertools.pairwise(segments):
        assert math.isclose(before.vel(before.t1), after.v0, abs_tol=1e-9)
        assert math.isclose(before.x1, after.x0, abs_tol=1e-9)
    assert math.isclose(segments[-1].x1, -50.0, abs_tol=1e-9)
    assert math.isclose(segments[-1].vel(segments[-1].t1), 0.0, abs_tol=1e-9)


def test_tv_037_backlash_finishes_positive_ms57_ms35(ms: Harness) -> None:
    assert ms.cmd("B X?") == b":X=0.040000 A\r\n"
    at(ms, 10000)
    assert ms.cmd("M X=0") == ACK
    ms.idle()
    assert abs(ms.get("axes")["X"]["min_user_mm"] - -0.040) < 0.0001
    assert ms.cmd("W X") == b":A 0\r\n"


def test_tv_038_overshoot_quantised_ms58_ms36(ms: Harness) -> None:
    assert ms.cmd("OS X=.05 Y=0") == ACK
    assert ms.cmd("OS X?") == b":A X=0.049982\r\n"
    assert ms.cmd("B X=0") == ACK
    at(ms, 10000)
    assert abs(ms.get("axes")["X"]["max_user_mm"] - 1.049982) < 0.0001
    assert ms.cmd("W X") == b":A 10000\r\n"


def test_tv_045_wait_time_keeps_busy_ms56_ms81(ms: Harness) -> None:
    assert ms.cmd("WT X?") == b":X=0 A\r\n"
    assert ms.cmd("WT X=300") == ACK
    ms.cmd("M X=10")
    while ms.dev.axes[0].traj.moving(ms.t) or ms.dev.axes[0].pause_until is None:
        ms.wait(0.001)
    landed = ms.dev.axes[0].pause_until - 0.3
    ms.wait(landed + 0.1 - ms.t)
    assert ms.cmd("/") == b"B\r\n"
    assert ms.cmd("RS X+") == b":A P\r\n"
    ms.wait(landed + 0.4 - ms.t)
    assert ms.cmd("/") == b"N\r\n"


def test_landing_ms_adds_settling_ms53(make: type[Harness]) -> None:
    h = make(overrides={"knobs": {"landing_ms": 100}})
    h.cmd("B X=0")
    h.cmd("M X=20000")
    took = h.idle(step=0.001)
    assert abs(took - (Trapezoid(2.0, 5.1456, 0.07).duration + 0.1)) < 0.002


def test_maintain_3_clears_busy_at_landing_ms61(ms: Harness) -> None:
    ms.cmd("MA X=3")
    ms.cmd("WT X=300")
    ms.cmd("M X=10")
    ms.idle(step=0.001)
    assert ms.cmd("RS X") == b":A 14\r\n"
    ms.wait(0.31)
    assert ms.cmd("RS X") == b":A 10\r\n"


def test_tv_047_zero_balancing_blocks_ms98_ms33(ms: Harness) -> None:
    assert ms.cmd("AZ X") == b""
    assert ms.cmd("V") == b""
    ms.wait(0.5)
    assert ms.output() == b":A\r\n:A Version: USB-9.2k \r\n"
    assert ms.cmd("AZ X?") == b":A X=127\r\n"
    ms.input("az_fail", axis="X")
    ms.cmd("AZ X")
    ms.wait(0.5)
    assert ms.output() == b"NOT Zerod\r\n"


def test_halt_cancels_blocking_command_ms33_ms20(ms: Harness) -> None:
    assert ms.cmd("AZ X") == b""
    assert ms.send(b"W X\r\\\r") == b":N-21\r\n:A\r\n:A 0\r\n"
    ms.wait(1.0)
    assert ms.output() == b""


def test_tv_048_limits_and_home_follow_the_origin_ms49_ms69_ms68(ms: Harness) -> None:
    assert ms.cmd("SU X?") == b":A X=110.000\r\n"
    assert ms.cmd("H X=10000") == ACK
    assert ms.cmd("SU X?") == b":A X=111.000\r\n"
    assert ms.cmd("HM X?") == b":A X=1001.000\r\n"
    assert ms.cmd("W X") == b":A 10000\r\n"


def test_tv_049_here_and_zero_ms69_ms70(ms: Harness) -> None:
    assert ms.cmd("H X=1234 Y=4321 Z") == ACK
    assert ms.cmd("W X Y Z") == b":A 1234 4321 0\r\n"
    assert ms.cmd("Z") == ACK
    assert ms.cmd("W X Y Z") == b":A 0 0 0\r\n"


def test_tv_050_hardware_limit_stops_ms66_ms50_ms41_ms108(ms: Harness) -> None:
    assert ms.cmd("M X=2000000") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 600000\r\n"
    assert ms.cmd("RS X") == b":A 74\r\n"
    assert ms.cmd("RS X-") == b":A U\r\n"
    assert ms.cmd("DU Y") == b"34\r:A\r\n"


def test_tv_051_soft_limit_clamps_ms66_ms65(ms: Harness) -> None:
    assert ms.cmd("SU X=5") == ACK
    assert ms.cmd("M X=100000") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 50000\r\n"
    assert ms.cmd("RS X") == b":A 74\r\n"


def test_lower_limit_status_ms79(ms: Harness) -> None:
    ms.cmd("B X=0")
    ms.cmd("M X=-2000000")
    ms.idle()
    assert ms.cmd("RS X") == b":A 138\r\n"
    assert ms.cmd("RS X-") == b":A L\r\n"
    assert ms.cmd("DU Y") == b"35\r:A\r\n"


def test_tv_052_soft_limit_flags_and_z_rule_ms65_ms21(ms: Harness) -> None:
    at(ms, 10000)
    assert ms.cmd("SU X+") == ACK
    assert ms.cmd("SU X?") == b":A X=1.000\r\n"
    assert ms.cmd("SU X-") == ACK
    assert ms.cmd("SU X?") == b":A X=110.000\r\n"
    assert ms.cmd("SL Z=200") == ACK
    assert ms.cmd("SL Z?") == b":A Z=-110.000\r\n"


def test_tv_053_home_runs_to_first_limit_ms67_ms31(ms: Harness) -> None:
    assert ms.cmd("! X") == ACK
    assert ms.cmd("/") == b"B\r\n"
    assert ms.cmd("RS X+") == b":A B\r\n"
    ms.idle()
    assert ms.cmd("W X") == b":A 600000\r\n"
    assert ms.cmd("!") == b":N-3\r\n"


def test_tv_054_home_position_flags_ms68(ms: Harness) -> None:
    at(ms, 10000)
    assert ms.cmd("HM X+") == ACK
    assert ms.cmd("HM X?") == b":A X=1.000\r\n"
    assert ms.cmd("HM X-") == ACK
    assert ms.cmd("HM X?") == b":A X=1000.000\r\n"


def test_tv_055_spin_until_limit_ms71(ms: Harness) -> None:
    assert ms.cmd("@ X=100") == ACK
    assert ms.cmd("RS X") == b":A 15\r\n"
    assert ms.cmd("RS X+") == b":A s\r\n"
    ms.wait(11.0)
    assert ms.cmd("RS X") == b":A 74\r\n"
    assert ms.cmd("W X") == b":A 600000\r\n"
    assert ms.cmd("@ X=200") == b":N-4\r\n"
    assert ms.cmd("DU Y") == b"34\r:A\r\n"


def test_spin_stop_and_target_follows_ms71(ms: Harness) -> None:
    ms.cmd("SPIN X=-100")
    ms.wait(1.0)
    assert ms.cmd("@ X=0") == ACK
    assert ms.cmd("/") == b"N\r\n"
    position = ms.get("axes")["X"]
    assert position["target_counts"] == position["machine_counts"]
    assert ms.cmd("R X=0") == ACK
    ms.idle()
    assert ms.get("axes")["X"]["machine_counts"] == position["machine_counts"]


def test_tv_056_vector_ms72(ms: Harness) -> None:
    assert ms.cmd("VE X=10") == ACK
    assert ms.cmd("VE X?") == b":A X=7.680000\r\n"
    assert ms.cmd("/") == b"B\r\n"
    ms.wait(1.0)
    assert ms.cmd("VE X=0") == ACK
    ms.wait(0.1)
    assert ms.cmd("/") == b"N\r\n"
    assert ms.cmd("VE X?") == b":A X=0.000000\r\n"


def test_vector_probe_is_harmless_ms72(ms: Harness) -> None:
    assert ms.cmd("VE X=0") == ACK
    assert ms.cmd("/") == b"N\r\n"
    assert ms.cmd("W X") == b":A 0\r\n"


def test_tv_059_motor_control_ms75_ms64_ms21(ms: Harness) -> None:
    assert ms.cmd("MC X- Y+") == ACK
    assert ms.cmd("MC X? Y?") == b":A 0 1\r\n"
    assert ms.cmd("RS X") == b":A 8\r\n"
    assert ms.cmd("RS X-") == b":A D\r\n"
    assert ms.cmd("M X=1000") == ACK
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("MC X+") == ACK
    assert ms.cmd("RS X") == b":A 10\r\n"


def test_tv_060_halt_during_move_ms76_ms20(ms: Harness) -> None:
    assert ms.cmd("M X=100000") == ACK
    assert ms.send(b"\x5c\r") == b":N-21\r\n"
    assert ms.cmd("/") == b"N\r\n"


def test_tv_061_halt_when_idle_ms76_ms20(ms: Harness) -> None:
    assert ms.cmd("HALT") == ACK
    assert ms.send(b"\x5c\r") == ACK
    assert ms.send(b"\x5c junk\r") == ACK


def test_halt_target_becomes_position_ms76_ms51(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.5)
    ms.cmd("\\")
    stopped = ms.get("axes")["X"]["machine_counts"]
    assert ms.get("axes")["X"]["target_counts"] == stopped
    ms.cmd("R X=10")
    ms.idle()
    assert ms.get("axes")["X"]["machine_counts"] == stopped + 45


def test_tv_065_drift_correction_ms88_ms61(ms: Harness) -> None:
    ms.input("disturb", axis="X", um=5)
    ms.wait(0.2)
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("DU Y") == b":A\r\n"


def test_tv_066_held_disturbance_gives_up_ms61_ms88(ms: Harness) -> None:
    ms.input("disturb", axis="X", um=5, hold=True)
    ms.wait(0.6)
    assert ms.cmd("DU Y") == b"60\r:A\r\n"
    assert ms.cmd("MA X=4") == b":N-4\r\n"
    assert ms.cmd("MA X=2") == ACK
    ms.input("disturb", axis="X", um=0)
    assert ms.cmd("RS X") == b":A 14\r\n"
    ms.wait(0.2)
    assert ms.cmd("W X") == b":A 0\r\n"


def test_tv_067_runaway_disables_axis_ms62(ms: Harness) -> None:
    ms.input("disturb", axis="X", um=2000, hold=True)
    assert ms.cmd("RS X") == b":A 8\r\n"
    assert ms.cmd("RS X-") == b":A D\r\n"
    ms.wait(1.0)
    assert ms.cmd("DU Y") == b"30\r:A\r\n"


def test_tv_068_stall_ms88_ms41(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.2)
    assert ms.input("stall", axis="X") is True
    assert ms.cmd("/") == b"N\r\n"
    assert ms.cmd("DU Y") == b"20\r:A\r\n"


def test_tv_069_limit_switch_blocks_motion_ms87(ms: Harness) -> None:
    ms.input("limit", axis="X", end="upper", closed=True)
    assert ms.cmd("RS X") == b":A 74\r\n"
    assert ms.cmd("M X=10000") == ACK
    ms.idle()
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("DU Y") == b"34\r:A\r\n"


def test_limit_switch_closing_during_move_stops_it_ms87(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.5)
    ms.input("limit", axis="X", end="upper", closed=True)
    assert ms.cmd("/") == b"N\r\n"
    ms.input("limit", axis="X", end="upper", closed=False)
    assert ms.cmd("RS X") == b":A 10\r\n"


def test_move_complete_event(ms: Harness) -> None:
    ms.cmd("M X=1000 Y=-505")
    ms.idle()
    events = ms.take_events("move_complete")
    assert len(events) == 1
    assert events[0]["positions"] == {"X": "1000", "Y": "-505", "Z": "0"}


def test_superseded_move_does_not_complete(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.2)
    ms.cmd("M X=0")
    ms.idle()
    assert len(ms.take_events("move_complete")) == 1


def test_runaway_during_move_stops_the_disabled_axis_ms62_ms75(ms: Harness) -> None:
    """A disabled motor does not carry on with its move: the axis stops, not busy, `D`."""
    ms.cmd("M X=100000")
    ms.wait(0.3)
    ms.input("disturb", axis="X", um=2000)
    assert ms.cmd("RS X") == b":A 8\r\n"
    assert ms.cmd("/") == b"N\r\n"
    stopped = ms.cmd("W X")
    ms.wait(1.0)
    assert ms.cmd("W X") == stopped
    assert ms.cmd("DU Y") == b"30\r:A\r\n"


def test_cnts_during_move_lets_the_other_axes_complete_ms45_ms96(ms: Harness) -> None:
    """CNTS stops its axis; the rest of the move still completes (VB X bit 0 `N`)."""
    ms.cmd("VB X=1")
    ms.cmd("M X=100000 Y=20000")
    ms.wait(0.1)
    assert ms.cmd("C X=45396") == ACK
    ms.idle()
    ms.wait(0.1)
    assert ms.output() == b"N\r\n"
    assert ms.cmd("W Y") == b":A 20000\r\n"


@pytest.mark.parametrize("start", ["@ X=100", "VE X=1"])
def test_relative_move_ending_spin_or_vector_starts_from_position_ms71_ms72_ms51(
    ms: Harness, start: str
) -> None:
    """A new move ends SPIN/VE and their target is the position then, so `R` goes on from there."""
    ms.cmd(start)
    ms.wait(1.0)
    here = int(ms.cmd("W X")[3:])
    assert ms.cmd("R X=10000") == ACK
    ms.idle()
    assert ms.cmd("W X") == f":A {here + 10000}\r\n".encode()
