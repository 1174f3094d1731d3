"""AUTOFOCUS (§9.6) on profile `ms2000-af`: the rules around the test vectors, which run in
tests/conformance/ms2000 (TV-169…TV-180)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from emulator.devices.ms2000.modules.autofocus_curve import Adjust, FocusCurve, FocusScan
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
FAILED = b":N-5\r\n"
AF = "ms2000-af"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(AF)


def reply_after(ms: Harness, limit: float = 30.0, step: float = 0.01) -> tuple[bytes, float]:
    """Wait for the pending reply; returns it and how long it took."""
    start = ms.t
    while ms.t - start < limit:
        ms.wait(step)
        out = ms.output()
        if out:
            return out, ms.t - start
    raise AssertionError("no reply")


def z_units(ms: Harness) -> int:
    return int(ms.cmd("W Z").split()[1])


def test_adjustments_scale_offset_and_clamp(ms: Harness) -> None:
    """MS-AF-2, MS-AF-7: ×Y/100, ×2^Z, + (X − 50), clamped to 0…2047."""
    assert ms.cmd("AFADJ Y=50") == ACK
    assert ms.cmd("RA Z") == b":A 525\r\n"
    assert ms.cmd("AFADJ X=60 Y=100 Z=1") == ACK
    assert ms.cmd("RA Z") == b":A 2047\r\n"  # 2110 saturates
    ms.input("focus", peak_um=1000)  # far away: the baseline only
    assert ms.cmd("AFADJ X=0 Z=0") == ACK
    assert ms.cmd("RA Z") == b":A 0\r\n"


def test_lcd_segment_shows_the_value(ms: Harness) -> None:
    """§9.0: AUTOFOCUS's LCD segment is `FV nnnn`."""
    assert ms.get("lcd")[1].startswith("FV 1050 ")


def test_lines_wait_behind_a_run(ms: Harness) -> None:
    """MS-33: lines sent during a run are answered after its reply, in order."""
    ms.input("focus", peak_um=10)
    assert ms.cmd("AF") == b""
    assert ms.cmd("V") == b""
    reply, _ = reply_after(ms)
    assert reply == ACK + b":A Version: USB-9.2k \r\n"


def test_calibration_raises_gain_for_a_weak_signal(ms: Harness) -> None:
    """MS-AF-6 [choice]: a weak peak gets gain and amplitude up towards 1500."""
    ms.input("focus", amplitude=100, baseline=20)
    ms.cmd("AFC")
    assert reply_after(ms)[0] == ACK
    assert ms.cmd("AFADJ X? Y? Z?") == b":A X=0 Y=100 Z=3\r\n"  # peak 120 × 8 ≈ 960


def test_calibration_without_contrast_fails(ms: Harness) -> None:
    """MS-AF-6: no contrast `:N-5` (300 logged), AFADJ unchanged."""
    ms.input("focus", amplitude=0)
    ms.cmd("AFC")
    assert reply_after(ms)[0] == FAILED
    assert ms.cmd("AFADJ X? Y? Z?") == b":A X=50 Y=100 Z=0\r\n"


def test_at_button_and_in0_mode_3_start_silent_runs(ms: Harness) -> None:
    """MS-AF-3, MS-90: `@` and an IN0 edge in mode 3 start runs without a reply."""
    ms.input("focus", peak_um=10)
    ms.input("button", name="at", ms=100)
    ms.wait(0.2)
    assert ms.get("busy") is True
    ms.idle()
    assert 80 <= z_units(ms) <= 120
    ms.input("focus", peak_um=-10)
    assert ms.cmd("TTL X=3") == ACK
    ms.input("ttl_in0", pulse_ms=5)
    ms.wait(0.1)
    ms.idle()
    assert ms.output() == b""
    assert -120 <= z_units(ms) <= -80


def test_in0_mode_103_repeats(ms: Harness) -> None:
    """MS-90: mode 103 runs an autofocus every `RT X` ms, following a moving focus."""
    assert ms.cmd("RT X=500") == ACK
    assert ms.cmd("TTL X=103") == ACK
    ms.input("focus", peak_um=10)
    ms.wait(0.6)
    ms.idle()
    assert 80 <= z_units(ms) <= 120
    ms.input("focus", peak_um=20)
    ms.wait(0.6)
    ms.idle()
    assert 180 <= z_units(ms) <= 220
    assert ms.cmd("TTL X=0") == ACK
    ms.input("focus", peak_um=0)
    ms.wait(2)
    assert ms.get("busy") is False
    assert 180 <= z_units(ms) <= 220


def test_halt_ends_a_silent_run(ms: Harness) -> None:
    """MS-76: HALT stops an autofocus started by `@`; OUT0 mode 10 stays low."""
    assert ms.cmd("TTL Y=10") == ACK
    ms.input("button", name="at", ms=100)
    ms.wait(0.5)
    assert ms.cmd("\\") == b":N-21\r\n"
    ms.wait(5)
    assert ms.get("busy") is False
    assert ms.get("ttl_out0") == 0


def test_home_held_three_seconds_calibrates(ms: Harness) -> None:
    """MS-AF-6: home held over 3 s starts the calibration (no reply)."""
    ms.input("button", name="home", ms=3500)
    ms.wait(3.6)
    assert ms.get("busy") is True
    ms.idle()
    assert ms.output() == b""
    assert ms.cmd("AFADJ X?") == b":A X=0\r\n"


def test_be_f_functions(ms: Harness) -> None:
    """Appendix B: `BE F=9` runs an autofocus."""
    ms.input("focus", peak_um=10)
    assert ms.cmd("BE F=9") == ACK
    ms.wait(0.1)
    ms.idle()
    assert 80 <= z_units(ms) <= 120


def test_ss_z_saves_af_and_afadj_only(ms: Harness) -> None:
    """MS-AF-1, MS-AF-7, MS-111: AF and AFADJ are saved; AFC, AL and AM revert at power-up."""
    for command in ("AF X=5 Y=0.2 Z=1 F=30", "AFADJ X=40 Y=90 Z=2", "AFC X=30", "AL X=20", "AM X=1"):
        assert ms.cmd(command) == ACK
    assert ms.cmd("SS Z") == ACK
    ms.input("power_cycle")
    assert ms.cmd("AF X? Y? Z? F?") == b":A X=5 Y=0.200000 Z=1 F=30\r\n"
    assert ms.cmd("AFADJ X? Y? Z?") == b":A X=40 Y=90 Z=2\r\n"
    assert ms.cmd("AFC X?") == b":A X=18\r\n"
    assert ms.cmd("AL X?") == b":A X=80\r\n"
    assert ms.cmd("AM X?") == b":A X=0\r\n"


def test_unsaved_afadj_reverts_at_power_up(ms: Harness) -> None:
    """MS-AF-7: without `SS Z` the gain is back to 0 after a power cycle."""
    assert ms.cmd("AFADJ Z=3") == ACK
    ms.input("power_cycle")
    assert ms.cmd("AFADJ Z?") == b":A Z=0\r\n"


def test_commands_need_the_module(make: Callable[..., Harness]) -> None:
    """MS-118: without AUTOFOCUS its words are unknown, IN0 mode 3 and OUT0 mode 10 are `:N-4`;
    `RA Z` reads 0 (MS-117)."""
    ms = make("ms2000")
    for command in ("AF", "AFC", "AFADJ X?", "AFINFO", "AM X?", "AL X?"):
        assert ms.cmd(command) == b":N-1\r\n"
    assert ms.cmd("TTL X=3") == b":N-4\r\n"
    assert ms.cmd("TTL Y=10") == b":N-4\r\n"
    assert ms.cmd("RA Z") == b":A 0\r\n"


def test_focus_input_checks_and_echoes(ms: Harness) -> None:
    """Appendix B: `focus` changes only the parameters given; bad values are refused."""
    curve = ms.input("focus", peak_um=3, noise=2.5, seed=7)
    assert curve == {
        "peak_um": 3.0,
        "width_um": 5.0,
        "amplitude": 1000.0,
        "baseline": 50.0,
        "noise": 2.5,
        "seed": 7,
    }
    for bad in ({"width_um": 0}, {"noise": -1}, {"seed": 1.5}, {"colour": 1}):
        with pytest.raises(Exception, match="focus"):
            ms.input("focus", **bad)
    with pytest.raises(Exception, match="clutch"):
        ms.input("clutch", engaged="no")


def test_noise_is_deterministic_for_a_seed() -> None:
    """MS-AF-2: noise depends on the seed and the frame only."""
    curve = FocusCurve(noise=10.0, seed=3)
    assert curve.raw(0.0, 42) == curve.raw(0.0, 42)
    assert curve.raw(0.0, 42) != curve.raw(0.0, 43)
    assert FocusCurve(noise=10.0, seed=4).raw(0.0, 42) != curve.raw(0.0, 42)
    assert FocusCurve().raw(0.0, 42) == 1050.0


def test_noisy_run_still_finds_the_peak(ms: Harness) -> None:
    """MS-AF-2, MS-AF-3: with noise the filtered peak stays near the curve's."""
    ms.input("focus", peak_um=10, noise=20, seed=1)
    ms.cmd("AF")
    assert reply_after(ms)[0] == ACK
    assert 70 <= z_units(ms) <= 130


def test_scan_bookkeeping() -> None:
    """MS-AF-3: the filter needs three samples; the hill needs a rise of the minimum contrast."""
    scan = FocusScan()
    for z, v in [(0.0, 100), (1.0, 200), (2.0, 300), (3.0, 400), (4.0, 100), (5.0, 100)]:
        scan.add(z, v)
    assert scan.first == 200 and scan.best == 300 and scan.best_um == 2.0
    assert scan.contrast == 100
    assert scan.past_hill(50, 18)
    assert not scan.past_hill(50, 150)
    assert Adjust(zero=0).apply(30) == 0
