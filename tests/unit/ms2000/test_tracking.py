"""TRACKING (PhotoTrack, §9.12) on the manual clock: MS-TRACK-1…MS-TRACK-3 and the §9.0 rule that
CRISP serves `LK`/`LR`/`UL` when a build lists both."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from emulator.device import ControlError
from emulator.devices.ms2000.calls import Call, Reply
from emulator.devices.ms2000.modules import MODULES, Handler, Module
from emulator.devices.ms2000.modules.tracking import Tracking
from emulator.devices.ms2000.modules.tracking_signal import errors
from emulator.profiles.profile import load_profile
from tests.unit.ms2000.conftest import Harness, schema_rebuilt

ACK = b":A\r\n"
EVEN = {"q1": 100, "q2": 100, "q3": 100, "q4": 100}
#: ex = +1/3, ey = 0: the object sits towards +X
RIGHT = {"q1": 200, "q2": 100, "q3": 100, "q4": 200}


@pytest.fixture
def track() -> Harness:
    return Harness("ms2000-track")


def state(h: Harness) -> bytes:
    return h.cmd("LK X?")


def x_target_um(h: Harness) -> float:
    return float(h.get("axes")["X"]["target_user_mm"]) * 1000


def test_toggle_and_pause_below_sum_min_ms_track_1(track: Harness) -> None:
    """MS-TRACK-1: bare `LK` toggles I → T → I; a sum below `LK Z` pauses (P) and recovers (T)."""
    track.input("pmt", **EVEN)
    assert state(track) == b":A I\r\n"
    assert track.cmd("LK") == ACK
    assert state(track) == b":A T\r\n"
    assert track.cmd("LK Z=1000") == ACK
    assert state(track) == b":A P\r\n"
    assert track.cmd("LK Z?") == b":A 1000 \r\n"
    track.input("pmt", q1=400, q2=400, q3=400, q4=400)
    assert state(track) == b":A T\r\n"
    assert track.cmd("LK") == ACK
    assert state(track) == b":A I\r\n"
    assert [e["state"] for e in track.take_events("tracking")] == ["T", "P", "T", "I"]


def test_lk_bad_values_change_nothing_ms_track_1(track: Harness) -> None:
    """MS-TRACK-1: `LK F` is 0–3 and `LK Z` 0–65535; a bad item refuses the whole command."""
    assert track.cmd("LK F=4") == b":N-4\r\n"
    assert track.cmd("LK Z=70000") == b":N-4\r\n"
    assert track.cmd("LK Z=500 F=9") == b":N-4\r\n"
    assert track.cmd("LK Q?") == b":N-2\r\n"
    assert track.cmd("LK T=5") == b":N-4\r\n"
    assert track.cmd("LK Z? F?") == b":A 100 0 \r\n"
    assert track.cmd("LK F=3") == ACK
    assert track.cmd("LK F?") == b":A 3 \r\n"


def test_parameters_and_report_ms_track_2(track: Harness) -> None:
    """MS-TRACK-2: `LR` F6 settings with range checks; bare `LR Z` is a bare multi-line report;
    `UL` settings, bare `UL` stops tracking."""
    assert track.cmd("LR X? Y? F?") == b":A X=1.000000 Y=0.500000 F=0.010000\r\n"
    assert track.cmd("LR Z?") == b":A Z=0.050000\r\n"
    assert track.cmd("LR Y=0.2 X=2.5") == ACK
    assert track.cmd("LR X? Y?") == b":A X=2.500000 Y=0.200000\r\n"
    assert track.cmd("LR Y=0") == b":N-4\r\n"
    assert track.cmd("LR X=101") == b":N-4\r\n"
    report = track.cmd("LR Z")
    assert report.endswith(b"\r\n") and not report.startswith(b":A")
    lines = report[:-2].split(b"\r")
    assert lines[0] == b"PhotoTrack state: I" and b"Cal value: 2.500000" in lines
    assert track.cmd("UL X? Y? Z? F?") == b":A X=0.000000 Y=1.000000 Z=1.000000 F=2.000000\r\n"
    assert track.cmd("UL X=2") == b":N-4\r\n"
    assert track.cmd("UL F=3") == b":N-4\r\n", "only three axes: index 0–2"
    track.input("pmt", **EVEN)
    track.cmd("LK")
    assert track.cmd("UL") == ACK
    assert state(track) == b":A I\r\n"


def test_loop_moves_xy_every_10_ms_ms_track_3(track: Harness) -> None:
    """MS-TRACK-3: each 10 ms cycle moves X by ex × cal_value µm through the motion model (here
    1/3 µm per cycle, each landed within a few ms), not busy; Y stays (ey = 0)."""
    track.input("pmt", **RIGHT)
    track.cmd("LK")
    track.wait(0.108)  # cycles at 10, 20, … 100 ms
    assert x_target_um(track) == pytest.approx(10 / 3, abs=0.05)
    assert track.get("axes")["Y"]["target_user_mm"] == 0
    assert track.cmd("/") == b"N\r\n"
    assert track.cmd("LR X=3") == ACK
    track.wait(0.1)
    assert x_target_um(track) == pytest.approx(10 / 3 + 10, abs=0.05)


def test_quadrant_order_turns_the_error_ms_track_3() -> None:
    """MS-TRACK-3: the channels are counter-clockwise from +X+Y, turned by `LK F` × 90°."""
    assert errors((200, 100, 100, 200), 0) == pytest.approx((600, 1 / 3, 0))
    assert errors((200, 100, 100, 200), 1) == pytest.approx((600, 0, 1 / 3))
    assert errors((200, 100, 100, 200), 2) == pytest.approx((600, -1 / 3, 0))
    assert errors((0, 0, 0, 0), 0) == (0.0, 0.0, 0.0)


def test_stage_follows_a_moving_object_ms_track_3(track: Harness) -> None:
    """MS-TRACK-3 with a simulated object: the loop centres a still object, then keeps up with one
    drifting at 20 µm/s in Y."""
    track.input("pmt", x_um=8.0, y_um=-4.0, sigma_um=5.0, brightness=1000)
    track.cmd("LK")
    track.wait(1.0)
    axes = track.get("axes")
    assert axes["X"]["user_mm"] * 1000 == pytest.approx(8.0, abs=0.1)
    assert axes["Y"]["user_mm"] * 1000 == pytest.approx(-4.0, abs=0.1)
    track.input("pmt", x_um=8.0, y_um=-4.0, vy_um_s=20.0, sigma_um=5.0)
    track.wait(2.0)
    y_um = track.get("axes")["Y"]["user_mm"] * 1000
    assert y_um == pytest.approx(-4.0 + 40.0, abs=2.0)
    assert state(track) == b":A T\r\n"


def test_detector_mounting_must_match_quad_order_ms_track_3(track: Harness) -> None:
    """MS-TRACK-3: a detector turned by a quarter tracks once `LK F=1` says so."""
    track.input("pmt", x_um=6.0, sigma_um=5.0, quarter_turns=1)
    assert track.cmd("LK F=1") == ACK
    track.cmd("LK")
    track.wait(1.0)
    assert track.get("axes")["X"]["user_mm"] * 1000 == pytest.approx(6.0, abs=0.1)


def test_range_exceeded_stops_with_error_ms_track_2(track: Harness) -> None:
    """MS-TRACK-2: moving more than `LR Y` from where tracking began stops it in `E`; `LK` restarts."""
    track.cmd("LR X=50 Y=0.01")
    track.input("pmt", q1=300, q2=0, q3=0, q4=300)  # ex = 1: 50 µm per cycle
    track.cmd("LK")
    track.wait(0.5)
    assert state(track) == b":A E\r\n"
    assert track.get("tracking")["reason"] == "range"
    held = x_target_um(track)
    track.wait(0.2)
    assert x_target_um(track) == held, "no correction after the error"
    assert track.cmd("LK") == ACK
    assert state(track) == b":A T\r\n"


def test_calibration_sets_the_gain_ms_track_1(track: Harness) -> None:
    """MS-TRACK-1: `LK X` calibrates (state C) from the error slope over `LR F`, then returns to I;
    with no spot to measure it ends in E."""
    track.input("pmt", x_um=0.0, sigma_um=5.0)
    assert track.cmd("LK X") == ACK
    assert state(track) == b":A C\r\n"
    track.wait(0.35)
    assert state(track) == b":A I\r\n"
    cal = float(track.cmd("LR X?")[5:-2])
    # slope of erf(d / (σ√2)) at 0 over ±5 µm, ten cycles to null an offset
    assert cal == pytest.approx(0.7, abs=0.05)
    assert track.get("axes")["X"]["target_user_mm"] == pytest.approx(0, abs=1e-6)
    track.input("pmt", **EVEN)
    track.cmd("LK X")
    track.wait(0.35)
    assert state(track) == b":A E\r\n"
    assert track.cmd("LR X?") == f":A X={cal:.6f}\r\n".encode(), "a failed calibration keeps the gain"


def test_buttons_and_halt_ms_track_1(track: Harness) -> None:
    """MS-TRACK-1: `@` short toggles, `@` long calibrates, `home` extra-long resets; HALT stops (MS-76)."""
    track.input("pmt", **EVEN)
    track.input("button", name="at", ms=100)
    track.wait(0.2)
    assert state(track) == b":A T\r\n"
    track.cmd("\\")
    assert state(track) == b":A I\r\n"
    track.input("button", name="at", ms=1500)
    track.wait(1.6)
    assert state(track) == b":A C\r\n"
    track.input("button", name="home", ms=3500)
    track.wait(3.6)
    assert state(track) == b":A I\r\n"


def test_report_lcd_and_settings_saved_ms_track_3(track: Harness) -> None:
    """MS-TRACK-3 and §9.0: IN0 mode 5 reports end with the sum; LCD segment `<state> <sum>`;
    settings kept by `SS Z` (MS-111), tracking off after a reset."""
    track.input("pmt", **RIGHT)
    assert track.cmd("TTL X=5") == ACK
    track.input("ttl_in0", pulse_ms=5)
    track.wait(0.25)
    assert track.output().split(b"\r\n")[0].split()[-1] == b"600"
    assert track.get("lcd")[1].startswith("I 600")
    track.cmd("TTL X=0")
    track.cmd("LK Z=250")
    track.cmd("LK")
    assert track.cmd("SS Z") == ACK
    track.cmd("LK Z=5")
    assert track.cmd("~") == ACK
    assert track.cmd("LK Z?") == b":A 250 \r\n"
    assert state(track) == b":A I\r\n"


def test_pmt_input_is_validated(track: Harness) -> None:
    """Appendix B `pmt`: numbers only, quadrants or an object, not both."""
    for bad in ({"q1": -1}, {"q1": "a"}, {"q1": 1, "x_um": 2}, {"zz": 1}, {"x_um": 0, "quarter_turns": 5}):
        with pytest.raises(ControlError):
            track.input("pmt", **bad)
    assert track.get("tracking")["sum"] == 0


class FocusLockStandIn(Module):
    """Test-only stand-in for CRISP: the same three words, declaring that it outranks TRACKING."""

    name = "CRISP"
    outranks = frozenset({"TRACKING"})

    def handlers(self) -> dict[str, Handler]:
        return {key: self.answer for key in ("LK", "LR", "UL")}

    def answer(self, call: Call) -> Reply:
        return Reply.text(":A CRISP")


@pytest.fixture
def crisp_stand_in(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Register the stand-in unless the real CRISP module is registered."""
    if "CRISP" in MODULES:
        yield
        return
    monkeypatch.setitem(MODULES, "CRISP", FocusLockStandIn)
    with schema_rebuilt():
        yield


@pytest.mark.parametrize(
    "modules",
    [["LL COMMANDS", "INO_INT", "CRISP", "TRACKING"], ["LL COMMANDS", "INO_INT", "TRACKING", "CRISP"]],
)
def test_crisp_serves_lk_lr_ul_beside_tracking_section_9_0(crisp_stand_in: None, modules: list[str]) -> None:
    """§9.0: with CRISP and TRACKING both listed, CRISP serves `LK`, `LR` and `UL`, in either
    profile order; TRACKING stays idle."""
    h = Harness(load_profile("ms2000-track", {"modules": modules}))
    h.input("pmt", **EVEN)
    table = h.dev.modules.handlers()
    for key in ("LK", "LR", "UL"):
        assert not isinstance(getattr(table[key], "__self__", None), Tracking), key
    for command in ("LK", "LR Z", "UL"):
        reply = h.cmd(command)
        if MODULES["CRISP"] is FocusLockStandIn:
            assert reply == b":A CRISP\r\n"
    assert h.get("tracking")["state"] == "I"
