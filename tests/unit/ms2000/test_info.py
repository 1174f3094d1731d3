"""Information and housekeeping commands (§7) on the model, beyond the test vectors, which run in
tests/conformance/ms2000 (TV-93…TV-104, TV-113, TV-115)."""

from __future__ import annotations

from protocols.ms2000 import split_lines
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def test_info_two_axes_separated_by_empty_line_ms106(ms: Harness) -> None:
    lines = ms.cmd("INFO Y X").decode().rstrip("\r\n").split("\r")
    assert len(lines) == 43 and lines[21] == ""
    assert lines[0].startswith("Axis Name    :  X") and lines[22].startswith("Axis Name    :  Y")


def test_trajectory_and_controller_log_ms108(ms: Harness) -> None:
    assert ms.cmd("DU") == ACK
    ms.cmd("M X=10000")
    ms.idle()
    lines = split_lines(ms.cmd("DU"))
    assert lines[-1] == b":A" and len(lines) >= 3
    assert lines[0].split()[1:4] == [b"X", b"45396", b"0"]
    assert ms.cmd("DU F") == b"On time: 0 s\rXY distance: 1.000000 mm\rMoves: 1\r:A\r\n"


def test_error_log_clock_marks_ms41(ms: Harness) -> None:
    ms.wait(1200.5)
    assert ms.cmd("DU Y") == b"255\r255\r:A\r\n"


def test_error_log_clock_marks_off_ms41(make: type[Harness]) -> None:
    h = make(overrides={"knobs": {"error_log_clock_marks": False}})
    h.wait(601)
    assert h.cmd("DU Y") == b":A\r\n"


def test_error_log_keeps_64_entries_ms41(ms: Harness) -> None:
    for code in range(70):
        ms.input("log_error", code=code)
    assert len(ms.get("error_log")) == 64
    assert ms.get("error_log")[0] == 69


def test_lcd_module_status_line(ms: Harness) -> None:
    ms.wait(65)
    top, bottom = ms.get("lcd")
    assert bottom == "RB 0/0 L 0 00:01:05"
    assert top.startswith("X0.000 Y0.000")
    assert all(len(line) <= 20 for line in (top, bottom))


def test_module_command_absent_from_xy_build_ms118(make: type[Harness]) -> None:
    h = make("ms2000-xy")
    assert h.cmd("LED X?") == b":N-1\r\n"
    assert h.cmd("TTL Y=9") == b":N-4\r\n"
    lines = [b"STD_XY", b"Motor Axes: X Y", b"CMDs: XYZFTR", b"BootLdr V:1", b"Hdwr REV.E"]
    assert h.cmd("BU X") == b"\r".join([*lines, b"LL COMMANDS", b"RING BUFFER 50", b"INO_INT"]) + b"\r\n"


def test_info_ramp_steps_round_half_away_ms106_ms48(ms: Harness) -> None:
    """Max Ramp Stps = round(AC / servo_ms): 15 / 6 = 2.5 gives 3, as the firmware rounds."""
    ms.cmd("AC X=15")
    row = ms.cmd("I X").split(b"\r")[3]
    assert row.endswith(b"Max Ramp Stps:         3"), row
