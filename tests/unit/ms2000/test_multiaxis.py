"""MULTIAXIS MOVES (§9.13) on the manual clock: the rest of MS-MULTI-1 and MS-MULTI-2 beyond the test
vectors, which run in tests/conformance/ms2000 (TV-208, TV-209).

These run on the test-only profile `ms2000-all-modules` (X and Y linear).
"""

from __future__ import annotations

import math

import pytest

from emulator.devices.ms2000.modules.multiaxis_path import Geometry, PathMotion, Pattern, Sample, segments
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def multi() -> Harness:
    return Harness("ms2000-all-modules")


def xyz(h: Harness) -> tuple[float, float, float]:
    axes = h.get("axes")
    return axes["X"]["user_mm"], axes["Y"]["user_mm"], axes["Z"]["user_mm"]


def state(h: Harness) -> str:
    return str(h.get("multi")["state"])


def test_circle_is_followed_over_time_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1: without lead-in the start is the circle's point at angle 0; at 0.5 mm/s on a
    1 mm radius the stage is at angle t/2, mid-path, and back at the start after one turn."""
    multi.cmd("MM X=1 Y=0.5 F=64")
    multi.cmd("MM")
    for t in (0.4, 1.0, 3.3, 7.0):
        multi.advance(t)
        x, y, _ = xyz(multi)
        assert (x, y) == pytest.approx((math.cos(t / 2) - 1, math.sin(t / 2)), abs=2e-5)
        assert multi.get("axes")["X"]["status_byte"] & 1
    multi.idle()
    assert multi.t == pytest.approx(4 * math.pi, abs=0.05)
    assert multi.cmd("W X Y") == b":A 0 0\r\n"
    assert state(multi) == "I"


def test_manual_input_is_refused_while_running_ms_multi_2(multi: Harness) -> None:
    """MS-MULTI-2: the joystick does not take the pattern's axes."""
    multi.cmd("MM X=1 Y=0.5 F=64")
    multi.cmd("MM")
    multi.input("joystick", x=1.0, y=0.0)
    multi.wait(1.0)
    x, y, _ = xyz(multi)
    assert math.hypot(x + 1, y) == pytest.approx(1.0, abs=1e-5)


def test_lead_in_then_circle_about_the_start_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1 bit 0: the start is the centre; state L while moving out along X, then C."""
    multi.cmd("MM X=0.5 Y=1 F=65")
    multi.cmd("MM")
    assert multi.cmd("MM R?") == b":A R=76.000000\r\n"
    multi.wait(0.6)
    assert state(multi) == "C"
    for _ in range(10):
        multi.wait(0.13)
        x, y, _ = xyz(multi)
        assert math.hypot(x, y) == pytest.approx(0.5, abs=2e-5)
    assert "MM C" in multi.get("lcd")[1]


def test_ramped_repeating_circle_and_halt_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1 bits 1 and 2: the speed ramps up over AC; the pattern repeats until HALT."""
    multi.cmd("MM X=0.2 Y=1 F=70")
    multi.cmd("MM")
    multi.wait(0.035)  # half of X's 70 ms ramp: a quarter of the cruise distance
    x, y, _ = xyz(multi)
    assert math.atan2(y, x + 0.2) * 0.2 == pytest.approx(0.25 * 0.035, rel=0.1)
    multi.wait(5.0)  # four turns
    assert state(multi) == "C"
    assert multi.get("multi")["turns"] > 3
    assert multi.cmd("\\") == b":N-21\r\n"
    assert state(multi) == "I"
    assert multi.cmd("RS X+") == b":A  \r\n"


def test_spiral_grows_to_the_radius_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1 pattern 11: from the start as centre, the radius grows by the width per turn."""
    multi.cmd("MM X=1 Y=2 Z=0.25 F=192")
    multi.cmd("MM")
    radii = []
    while state(multi) != "I":
        multi.wait(0.25)
        x, y, _ = xyz(multi)
        radii.append(math.hypot(x, y))
    assert radii == sorted(radii)
    assert multi.cmd("W X Y") == b":A 10000 0\r\n"


def test_helix_raises_z_per_turn_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1 pattern 10: Z rises by the width per turn; Z is then one of its axes."""
    multi.cmd("MM X=0.5 Y=1 Z=0.1 F=128")
    multi.cmd("MM")
    multi.wait(math.pi / 4)  # a quarter of the π mm circumference at 1 mm/s
    assert xyz(multi)[2] == pytest.approx(0.025, abs=1e-4)
    assert multi.cmd("M Z=0") == b":N-5\r\n"
    multi.idle()
    assert multi.cmd("W X Y Z") == b":A 0 0 1000\r\n"


def test_restart_fast_circles_ms_multi_2(multi: Harness) -> None:
    """MS-MULTI-2: `R=82` starts fast circles, and while running adds a whole turn from there."""
    multi.cmd("MM X=0.5 Y=1 F=0")
    assert multi.cmd("MM R=82") == ACK
    multi.wait(math.pi / 2)
    assert multi.cmd("MM R=82") == ACK
    multi.wait(math.pi * 0.75)
    assert state(multi) == "C"  # one turn would have ended at π
    multi.idle()
    assert state(multi) == "I"


def test_start_needs_parameters_and_idle_axes_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1 [choice]: no radius or speed, a spiral without width, or busy axes: `:N-5`."""
    assert multi.cmd("MM") == b":N-5\r\n"
    multi.cmd("MM X=1 Y=1 F=192")
    assert multi.cmd("MM") == b":N-5\r\n"
    multi.cmd("MM F=64")
    multi.cmd("M X=100000")
    assert multi.cmd("MM") == b":N-5\r\n"
    multi.idle()
    assert multi.cmd("MM") == ACK
    assert multi.cmd("MM") == b":N-5\r\n"


def test_limit_ends_the_pattern_ms_multi_1(multi: Harness) -> None:
    """A pattern that would leave the travel stops at the limit and logs it [choice]."""
    multi.cmd("SU X=0.5")
    multi.cmd("MM X=1 Y=2 F=65")
    multi.cmd("MM")
    multi.idle()
    assert state(multi) == "I"
    assert xyz(multi)[0] <= 0.5
    assert 34 in multi.get("error_log")


def test_parameters_saved_with_ss_z_ms_multi_1(multi: Harness) -> None:
    """MS-MULTI-1: `SS Z` keeps the parameters over a power cycle."""
    multi.cmd("MM X=2 Y=0.25 Z=0.1 F=198")
    assert multi.cmd("SS Z") == ACK
    multi.input("power_cycle")
    assert multi.cmd("MM X? Y? Z? F?") == b":A X=2.000000 Y=0.250000 Z=0.100000 F=198\r\n"


def test_segments_land_on_the_path() -> None:
    """multiaxis_path: each axis's segments pass through the sampled points of the curve."""
    geometry = Geometry(Pattern.CIRCLE, 0.0, 0.0, 0.0, 1.0, 0.0)
    motion = PathMotion(geometry, 1.0, None, 10.0, 2 * math.pi, Sample(0.0, 0.0, 1.0))
    samples = [motion.now] + [motion.step(0.006) for _ in range(20)]
    for coordinate in (0, 1):
        path = segments(motion, samples, coordinate, 1000.0)
        for segment, sample in zip(path, samples[1:], strict=True):
            expected = geometry.point(sample.theta)[coordinate] * 1000
            assert segment.x1 == pytest.approx(expected, abs=1e-9)
