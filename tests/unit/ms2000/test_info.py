"""Information and housekeeping commands (§7): TV-93…TV-104, TV-113, TV-115."""

from __future__ import annotations

from protocols.ms2000 import split_lines
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"

#: the INFO sample of the specification (axis X of the default profile at rest at the origin)
INFO_X = [
    "Axis Name    :  X                Limits Status:  ",
    "Input Device :      JS_X [J]     In_Dev Sign  :         1",
    "Max Lim      :   110.000 [SU]    Min Lim      :  -110.000 [SL]",
    "Ramp Time    :        70 (ms)[AC]Max Ramp Stps:        12",
    "Run Speed    :   5.14560(mm/s)[S]vmax_enc     :      1401",
    "Servo Lp Time:         6 (ms)    Ramp Length  :     15312 (enc)",
    "dv_enc       :       116         LL Axis ID   :        24",
    "Drift Error  :  0.000400 (mm)[E] enc_drift_err:        18",
    "Finish Error :  0.000022 (mm)[PC}enc_finsh_err:         1",
    "Backlash     :  0.040000 (mm)[B] enc_backlash :      1815",
    "Kp           :       100 [KP]    Ki           :        20 [KI]",
    "Kv           :        26 [KV]    Kd           :         0 [KD]",
    "Axis Enable  :         3 [MC]    Motor Enable :         0",
    "CMD_stat     :   NO_MOVE         Move_stat    :      IDLE",
    "Current pos  :    0.0000 (mm)    enc position :         0",
    "Target pos   :    0.0000 (mm)    enc target   :         0",
    "enc pos error:         0         EEsum        :         0",
    "Lst Stle Time:         0 (ms)    Av Settle Tim:         0 (ms)",
    "Home position:   1000.00 (mm)    Motor Signal :       128 (DAC)",
    "mm/sec/DAC_ct:   0.05500 [D]     Enc Cnts/mm  :  45396.00 [C]",
    "Wait Time    :         0 [WT]    Button Enable:        31 [BE]",
]


def test_tv_093_build_ms101(ms: Harness) -> None:
    assert ms.cmd("BU") == b"STD_XYZ\r\n"


def test_tv_094_build_modules_ms102_ms15(ms: Harness) -> None:
    assert ms.cmd("BU X") == (
        b"STD_XYZ\rMotor Axes: X Y Z\rCMDs: XYZFTR\rBootLdr V:1\rHdwr REV.E\r"
        b"LL COMMANDS\rRING BUFFER 50\rINO_INT\rLED DIMMER\r\n"
    )


def test_tv_095_ring_buffer_line_without_size_ms102(make: type[Harness]) -> None:
    h = make(overrides={"knobs": {"bu_x_ring_buffer_size": False}})
    assert b"\rRING BUFFER\rINO_INT\r" in h.cmd("BU X")


def test_tv_096_user_string_ms103(ms: Harness) -> None:
    assert ms.cmd("BU Y-") == ACK
    assert ms.cmd("BU Y=97") == ACK
    assert ms.cmd("BU Y=98") == ACK
    assert ms.cmd("BU Y?") == b"ab\r\n"
    assert ms.cmd("BU Y=127") == b":N-4\r\n"
    for _ in range(18):
        ms.cmd("BU Y=99")
    assert ms.cmd("BU Y=99") == b":N-4\r\n"
    assert ms.cmd("BU Y-") == ACK
    assert ms.cmd("BU Y?") == b"\r\n"


def test_tv_097_volatile_counter_ms104_ms34(ms: Harness) -> None:
    assert ms.cmd("BU Z?") == b":A 0\r\n"
    assert ms.cmd("BU Z-") == ACK
    assert ms.cmd("BU Z?") == b":A 65535\r\n"
    assert ms.cmd("BU Z+") == ACK
    assert ms.cmd("BU Z?") == b":A 0\r\n"
    assert ms.cmd("BU Z=70000") == b":N-4\r\n"


def test_tv_098_who_ms105(ms: Harness) -> None:
    assert ms.cmd("N") == b":A ASI-MS2000-XYBR-Zs-USB\r\n"


def test_tv_099_info_layout_ms106_ms15(ms: Harness) -> None:
    assert ms.cmd("I X") == "\r".join(INFO_X).encode() + b"\r\n"


def test_tv_100_info_pc_tag_fixed_ms106(make: type[Harness]) -> None:
    reply = make(overrides={"knobs": {"info_fix_pc_tag": True}}).cmd("I X").split(b"\r")
    assert reply[8] == b"Finish Error :  0.000022 (mm)[PC]enc_finsh_err:         1"


def test_info_two_axes_separated_by_empty_line_ms106(ms: Harness) -> None:
    lines = ms.cmd("INFO Y X").decode().rstrip("\r\n").split("\r")
    assert len(lines) == 43 and lines[21] == ""
    assert lines[0].startswith("Axis Name    :  X") and lines[22].startswith("Axis Name    :  Y")


def test_tv_101_info_absent_axis_silent_ms107_ms18(make: type[Harness]) -> None:
    h = make("ms2000-xy")
    assert h.cmd("INFO X").startswith(b"Axis Name    :  X")
    assert h.cmd("INFO Z") == b""
    h.wait(1.0)
    assert h.output() == b""
    assert h.cmd("/") == b"N\r\n"


def test_tv_102_info_absent_axis_error_ms107(make: type[Harness]) -> None:
    assert make("ms2000-xy", {"knobs": {"info_absent_axis": "error"}}).cmd("INFO Z") == b":N-2\r\n"


def test_tv_103_error_log_ms108_ms41(ms: Harness) -> None:
    assert ms.cmd("DU Y") == b":A\r\n"
    ms.input("log_error", code=87)
    ms.input("log_error", code=85)
    assert ms.cmd("DU Y") == b"85\r87\r:A\r\n"
    assert ms.cmd("DU X") == ACK
    assert ms.cmd("DU Y") == b":A\r\n"
    assert ms.cmd("DU F=999") == ACK


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


def test_tv_104_saveset_letters_ms110_ms31(ms: Harness) -> None:
    assert ms.cmd("SS Z") == ACK
    assert ms.cmd("SS Q") == b":N-2\r\n"
    assert ms.cmd("SS") == b":N-3\r\n"


def test_tv_113_lcd_text_ms116(ms: Harness) -> None:
    ms.input("dip", sw2="down")
    assert ms.get("lcd")[1] == "USB-9.2k"
    assert ms.cmd('LCD "hello"') == ACK
    assert ms.get("lcd")[1] == "hello"
    assert ms.cmd("LCD hello") == ACK
    assert ms.get("lcd")[1] == ""
    assert ms.cmd("UN") == ACK


def test_lcd_module_status_line(ms: Harness) -> None:
    ms.wait(65)
    top, bottom = ms.get("lcd")
    assert bottom == "RB 0/0 L 0 00:01:05"
    assert top.startswith("X0.000 Y0.000")
    assert all(len(line) <= 20 for line in (top, bottom))


def test_tv_115_commands_of_absent_modules_ms118(ms: Harness) -> None:
    assert ms.cmd("AR") == b":N-1\r\n"
    assert ms.cmd("CCB Z=1") == b":N-1\r\n"
    assert ms.cmd("WRDAC X=1") == b":N-1\r\n"


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
