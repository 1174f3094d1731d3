"""SCAN MODULE and ENC_INT (§9.3) on the manual clock: the rules around the test vectors, which run in
tests/conformance/ms2000 (TV-146…TV-153)."""

from __future__ import annotations

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: C of the ms2000-scan axes (counts per mm)
C = 45396


@pytest.fixture
def scan() -> Harness:
    return Harness("ms2000-scan")


@pytest.fixture
def area(scan: Harness) -> Harness:
    """The vectors' scan area: NR 0→1 mm divide 24, NV 0→0.1 mm in 3 lines."""
    for command in ("NR X=0 Y=1 Z=24", "NV X=0 Y=0.1 Z=3"):
        assert scan.cmd(command) == ACK
    return scan


def states_until_idle(h: Harness, step: float = 0.005, limit: float = 30.0) -> str:
    """The scan states seen (one per change) until the scan is idle and no axis busy."""
    seen = h.get("scan")["state"]
    start = h.t
    while h.get("scan")["state"] != "I" or h.dev.busy(h.t):
        assert h.t - start < limit, "scan still running"
        assert h.dev.busy(h.t), f"not busy in scan state {h.get('scan')['state']}"
        h.wait(step)
        state = h.get("scan")["state"]
        if state != seen[-1]:
            seen += state
    return seen


def scan_events(h: Harness) -> list[tuple[str, int, int | None]]:
    return [(e["ev"], e["line"], e.get("count")) for e in h.take_events() if e["ev"].startswith("scan_")]


def test_divide_acts_as_a_multiple_of_four_ms_scan_2(scan: Harness) -> None:
    """MS-SCAN-2: divide 27 counts pixels as 24 but reads back as set."""
    scan.cmd("NR X=0 Y=1 Z=27")
    assert scan.cmd("NR Z? F?") == b":A Z=27 F=1891\r\n"


def test_sweep_timing_overshoot_and_retrace_ms_scan_4(area: Harness) -> None:
    """MS-SCAN-4: the sweep starts one ramp distance (F × S × AC / 2000) before the start and ends one
    after the stop, so SYNC comes as the ramp ends; it runs at `S`; the retrace at 67 % of the
    maximum speed."""
    area.cmd("NV Z=1")
    area.cmd("S X=2")
    area.cmd("SN")
    ramp_mm = 2 * 70 / 2000
    states_until_idle(area)
    events = area.take_events()
    sync = next(e for e in events if e["ev"] == "scan_sync")
    completed = [e for e in events if e["ev"] == "move_complete"]
    # legs: slow move, fast start, sweep, retrace (to the start after the last line)
    assert [e["positions"]["X"] for e in completed] == ["0", "-700", "10700", "0"]
    sweep_start, sweep_end, retrace_end = (e["t"] for e in completed[1:])
    assert sync["t"] - sweep_start == pytest.approx(0.070, abs=1e-5)  # the begin is a whole count
    assert sweep_end - sweep_start == pytest.approx((1 + 2 * ramp_mm) / 2 + 0.070, abs=1e-4)
    retrace_speed = 0.67 * 7.68
    retrace_ramp_s = 0.070  # AC is a ramp time, whatever the speed
    assert retrace_end - sweep_end == pytest.approx((1 + ramp_mm) / retrace_speed + retrace_ramp_s, abs=1e-4)


def test_serpentine_alternates_direction_ms_scan_4_ms_scan_7(area: Harness) -> None:
    """MS-SCAN-4, MS-SCAN-7: serpentine sweeps alternate (backward ones in state e), SYNC comes
    where each sweep begins, and one final move returns the fast axis to its start."""
    area.cmd("SN F=1")
    area.cmd("TTL X=1")
    area.cmd("M Y=-500")
    area.idle()
    area.take_events()
    area.cmd("SN")
    assert states_until_idle(area) == "abcaeacgI"
    assert [count for ev, _, count in scan_events(area) if ev == "scan_pixels"] == [1891] * 3
    assert area.cmd("W X Y") == b":A 0 1000\r\n"


def test_dropped_pulses_log_85_ms_scan_6(area: Harness) -> None:
    """MS-SCAN-6: `scan_drop_pulses` removes pulses from the next line; the scan goes on."""
    area.cmd("TTL X=1")
    assert area.input("scan_drop_pulses", n=5) == {"pending": 5}
    area.cmd("SN")
    area.idle()
    assert [count for ev, _, count in scan_events(area) if ev == "scan_pixels"] == [1886, 1891, 1891]
    assert area.cmd("DU Y") == b"85\r:A\r\n"


def test_no_pixel_pulses_without_the_encoder_interrupt_ms_scan_4(area: Harness) -> None:
    """MS-SCAN-4: without `TTL X=1` only SYNC is produced, and nothing is logged."""
    area.cmd("SN")
    area.idle()
    assert [ev for ev, _, _ in scan_events(area)] == ["scan_sync"] * 3
    assert area.cmd("DU Y") == b":A\r\n"


def test_halt_ends_a_scan_at_once_ms_scan_6(area: Harness) -> None:
    """MS-SCAN-6: HALT stops the axes and the scan, logging 86."""
    area.cmd("SN")
    area.wait(0.3)
    assert area.cmd("\\") == b":N-21\r\n"
    assert area.get("scan")["state"] == "I"
    assert area.cmd("DU Y") == b"86\r:A\r\n"


def test_be_f8_toggles_a_scan(area: Harness) -> None:
    """Appendix B: function 8 starts and stops a scan."""
    area.cmd("BE F=8")
    area.wait(0.3)
    assert area.get("scan")["state"] not in "IP"
    area.cmd("BE F=8")
    assert area.get("scan")["state"] == "P"  # ramping down (MS-SCAN-5)
    area.idle()
    assert area.get("scan")["state"] == "I"


def test_settings_saved_with_ss_z_ms_scan_2_ms_scan_3(scan: Harness) -> None:
    """MS-SCAN-1…MS-SCAN-3: SN, NR and NV survive a power cycle after `SS Z`."""
    scan.cmd("NR X=0.5 Y=2 Z=40")
    scan.cmd("NV X=-1 Y=1 Z=11 F=1.5")
    scan.cmd("SN F=1")
    assert scan.cmd("SS Z") == ACK
    scan.input("power_cycle")
    assert scan.cmd("NR X? Y? Z?") == b":A X=0.500000 Y=2.000000 Z=40\r\n"
    assert scan.cmd("NV X? Y? Z? F?") == b":A X=-1.000000 Y=1.000000 Z=11 F=1.500000\r\n"
    assert scan.cmd("SN F?") == b":A F=1\r\n"


def test_enc_int_enables_ttl_x1_only_ms_scan_4(scan: Harness) -> None:
    """ENC_INT makes `TTL X=1` (encoder counting) available, not INO_INT's modes."""
    assert scan.cmd("TTL X=1") == ACK
    assert scan.cmd("TTL X=4") == b":N-4\r\n"
    assert "ENC_INT" in scan.cmd("BU X").decode()


def test_pixel_count_matches_c_of_the_fast_axis(scan: Harness) -> None:
    """MS-SCAN-2: pixels = floor(C × |stop − start| / divide)."""
    scan.cmd("NR X=-0.5 Y=0.5 Z=32")
    assert scan.cmd("NR F?") == f":A F={C // 32}\r\n".encode()


@pytest.mark.parametrize("abort", ["button", "command"])
def test_abort_ramps_down_at_the_move_deceleration_ms_scan_5(area: Harness, abort: str) -> None:
    """MS-SCAN-5, MS-SCAN-6: a momentary `@` (or bare `SN`) mid-sweep brakes the fast axis from its
    speed at the sweep's own deceleration (S / AC) and ends the scan: never faster than `S X`, at
    rest one braking distance on, busy until then, no later line, SYNC or pixel count, 86 logged."""
    area.cmd("S X=0.5")
    area.cmd("NR Y=0.2")
    area.cmd("TTL X=1")
    area.cmd("SN")
    x, y = area.dev.axis_named("X"), area.dev.axis_named("Y")
    assert x is not None and y is not None
    while area.get("scan")["state"] != "c":
        area.wait(0.005)
    mid_sweep = x.traj.first_reach(x.counts_of(0.0872), area.t)
    assert mid_sweep is not None
    area.advance(mid_sweep)
    area.take_events()
    speed = 0.5 * C  # counts/s
    decel = speed / 0.070  # the ramp of the sweep: S reached in AC
    # the abort acts on release for the button, at once for the command; the path is known till then
    t_abort = area.t + (0.1 if abort == "button" else 0.0)
    x_abort, v_abort = x.traj.pos(t_abort), x.traj.vel(t_abort)
    assert v_abort == pytest.approx(speed)
    if abort == "button":
        area.input("button", name="at", ms=100)
    else:
        assert area.cmd("SN") == ACK
    ramp_end = t_abort + v_abort / decel
    area.advance(t_abort)
    fastest = 0.0
    while area.dev.busy(area.t):
        assert area.t < ramp_end + 0.002, "still busy after the ramp"
        assert area.get("scan")["state"] == "P"
        fastest = max(fastest, abs(x.traj.vel(area.t)))
        area.wait(0.001)
    assert area.t >= ramp_end - 0.001, "idle before the ramp ended"
    assert fastest <= speed * (1 + 1e-9)
    assert x.pos(area.t) == pytest.approx(x_abort + v_abort**2 / (2 * decel), abs=1.0)
    assert area.get("scan")["state"] == "I"
    stopped_at = x.pos(area.t)
    area.wait(5.0)
    assert not area.dev.busy(area.t)
    assert (x.pos(area.t), y.pos(area.t)) == (stopped_at, 0.0)
    assert scan_events(area) == []
    assert area.cmd("DU Y") == b"86\r:A\r\n"
