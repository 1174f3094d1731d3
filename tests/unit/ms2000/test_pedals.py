"""PEDALS (§9.14): the tap/hold rule beyond TV-210 (tests/conformance/ms2000)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from emulator.device import ControlError
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(ALL_MODULES)


def test_tap_lands_at_release_and_down_goes_down(ms: Harness) -> None:
    """MS-PEDAL-2 [choice]: a tap is a tap only once the pedal is up again."""
    assert ms.cmd("PD X=0.01") == ACK
    ms.input("pedal", which="down", ms=200)
    ms.wait(0.15)
    assert ms.cmd("W Z") == b":A 0\r\n"
    ms.wait(1)
    assert ms.cmd("W Z") == b":A -100\r\n"


def test_hold_moves_at_the_rate_for_the_duration_and_is_not_busy(ms: Harness) -> None:
    """MS-PEDAL-2, MS-78: a 500 ms press at 1 mm/s moves 0.5 mm; pedal motion is never busy."""
    ms.input("pedal", which="up", ms=500)
    ms.wait(0.25)
    assert ms.cmd("/") == b"N\r\n"
    ms.wait(1)
    assert ms.cmd("W Z") == b":A 5000\r\n"
    assert ms.get("axes")["Z"]["target_counts"] == 10000


def test_hold_rate_is_clamped_to_the_axis_maximum(ms: Harness) -> None:
    """MS-PEDAL-1: Z's maximum is 1.92 mm/s, so a 5 mm/s rate moves 0.96 mm in 0.5 s."""
    assert ms.cmd("PD Y=5") == ACK
    assert ms.cmd("PD Y?") == b":A Y=5\r\n"
    ms.input("pedal", which="up", ms=500)
    ms.wait(1)
    assert ms.cmd("W Z") == b":A 9600\r\n"


def test_ranges_and_disabled_input(ms: Harness) -> None:
    """MS-PEDAL-1 ranges [choice]; a focus axis with manual input off (`J Z-`) ignores the pedal."""
    assert ms.cmd("PD X=0") == b":N-4\r\n"
    assert ms.cmd("PD Y=0.5 Z=3") == ACK
    assert ms.cmd("PD Y? Z?") == b":A Y=1 Z=3\r\n"
    assert ms.cmd("PD Q=1") == b":N-2\r\n"
    ms.cmd("J Z-")
    assert ms.input("pedal", which="up", ms=50) is False
    ms.wait(1)
    assert ms.cmd("W Z") == b":A 0\r\n"


def test_bad_input_is_refused(ms: Harness) -> None:
    with pytest.raises(ControlError, match="which"):
        ms.input("pedal", which="left", ms=50)
    with pytest.raises(ControlError, match="ms"):
        ms.input("pedal", which="up", ms=-1)


def test_without_the_module(make: Callable[..., Harness]) -> None:
    """MS-118: P0 has no PEDALS: `PEDAL` is unknown and so is the input."""
    p0 = make()
    assert p0.cmd("PEDAL X?") == b":N-1\r\n"
    with pytest.raises(ControlError, match="pedal"):
        p0.input("pedal", which="up", ms=50)
