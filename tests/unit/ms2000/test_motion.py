"""Units, moves, limits, home, spin, vector, halt, drift and runaway (§5, §6.1…§6.4) on the model:
the motion planner and what lies around the test vectors, which run in tests/conformance/ms2000
(TV-26…TV-38, TV-45, TV-47…TV-56, TV-59…TV-61, TV-65…TV-69)."""

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


def test_duration_matches_motion_trapezoid_ms52(ms: Harness) -> None:
    ms.cmd("B X=0")
    ms.cmd("M X=20000")
    took = ms.idle(step=0.001)
    expected = Trapezoid(2.0, 5.1456, 0.07).duration
    assert abs(took - expected) < 0.002


def test_replanning_keeps_velocity_continuous_ms63() -> None:
    segments = plan(0.0, 0.0, 100.0, -50.0, 200.0, 1000.0)
    assert segments[0].a < 0 and segments[0].v0 == 100.0
    for before, after in itertools.pairwise(segments):
        assert math.isclose(before.vel(before.t1), after.v0, abs_tol=1e-9)
        assert math.isclose(before.x1, after.x0, abs_tol=1e-9)
    assert math.isclose(segments[-1].x1, -50.0, abs_tol=1e-9)
    assert math.isclose(segments[-1].vel(segments[-1].t1), 0.0, abs_tol=1e-9)


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


def test_halt_cancels_blocking_command_ms33_ms20(ms: Harness) -> None:
    assert ms.cmd("AZ X") == b""
    assert ms.send(b"W X\r\\\r") == b":N-21\r\n:A\r\n:A 0\r\n"
    ms.wait(1.0)
    assert ms.output() == b""


def test_lower_limit_status_ms79(ms: Harness) -> None:
    ms.cmd("B X=0")
    ms.cmd("M X=-2000000")
    ms.idle()
    assert ms.cmd("RS X") == b":A 138\r\n"
    assert ms.cmd("RS X-") == b":A L\r\n"
    assert ms.cmd("DU Y") == b"35\r:A\r\n"


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


def test_vector_probe_is_harmless_ms72(ms: Harness) -> None:
    assert ms.cmd("VE X=0") == ACK
    assert ms.cmd("/") == b"N\r\n"
    assert ms.cmd("W X") == b":A 0\r\n"


def test_halt_target_becomes_position_ms76_ms51(ms: Harness) -> None:
    ms.cmd("M X=100000")
    ms.wait(0.5)
    ms.cmd("\\")
    stopped = ms.get("axes")["X"]["machine_counts"]
    assert ms.get("axes")["X"]["target_counts"] == stopped
    ms.cmd("R X=10")
    ms.idle()
    assert ms.get("axes")["X"]["machine_counts"] == stopped + 45


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
