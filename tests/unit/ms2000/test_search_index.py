"""SEARCH INDEX and SEEK LIMITS (§9.16): the rules around the test vectors, which run in
tests/conformance/ms2000 (TV-212…TV-215)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(ALL_MODULES)


def test_search_moves_to_the_middle_of_travel_and_replies_on_arrival(ms: Harness) -> None:
    """MS-SI-1, MS-33: from off-centre the reply waits for the index; the axis is busy (`B`) on the
    way; the soft limits return to their factory values."""
    ms.cmd("M X=20000")
    ms.idle()
    assert ms.cmd("SL X=-1") == ACK
    assert ms.cmd("SI X=500") == b""
    assert ms.cmd("RS X+") == b""  # queued behind the pending search (MS-33)
    ms.wait(5)
    assert ms.output() == ACK + b":A  \r\n"
    assert ms.cmd("W X") == b":A 500\r\n"
    assert ms.get("axes")["X"]["machine_counts"] == 0
    assert ms.cmd("SL X?") == b":A X=-109.950\r\n"


def test_search_is_busy_with_status_b_on_the_way(ms: Harness) -> None:
    """MS-81: SI is "other commanded motion": right status character `B` while it runs."""
    ms.cmd("M X=20000")
    ms.idle()
    ms.cmd("SI X=0")
    ms.wait(0.2)
    assert ms.get("busy") is True
    assert ms.get("axes")["X"]["activity"] == "home"
    ms.wait(5)
    assert ms.output() == ACK
    assert ms.get("busy") is False


def test_search_again_after_moving_off_and_zeroing(ms: Harness) -> None:
    """MS-SI-1: to search again, move off centre and zero first."""
    assert ms.cmd("SI X=0") == ACK
    ms.cmd("M X=1000")
    ms.idle()
    ms.cmd("Z")
    assert ms.cmd("SI X=0") == b""
    ms.wait(2)
    assert ms.output() == ACK
    assert ms.cmd("W X") == b":A 0\r\n"


def test_halt_cancels_a_search(ms: Harness) -> None:
    """MS-33, MS-76: HALT cuts a pending search short; it answers `:N-21`, HALT `:N-21` too."""
    ms.cmd("M X=20000")
    ms.idle()
    assert ms.cmd("SI X=0") == b""
    ms.wait(0.1)
    assert ms.cmd("\\") == b":N-21\r\n:N-21\r\n"
    assert ms.cmd("SI X?") == b":A X=0\r\n"
    assert ms.get("busy") is False


def test_seek_lower_limit_and_halt(ms: Harness) -> None:
    """MS-SI-2, MS-76: `SI Z=-1` goes to the lower limit; HALT stops a seek for good."""
    assert ms.cmd("SI Z=-1") == ACK
    ms.wait(1)
    assert ms.cmd("\\") == b":N-21\r\n"
    ms.wait(20)
    assert ms.get("busy") is False
    stopped = int(ms.cmd("W Z")[3:])
    assert -100000 < stopped < 0
    assert ms.cmd("SI Z=-1") == ACK
    ms.idle()
    assert ms.cmd("RS Z") == b":A 138\r\n"


def test_another_move_takes_a_seeking_axis_over(ms: Harness) -> None:
    """MS-63: a new move of the axis ends the seek; it goes where the move says."""
    ms.cmd("SI Z=1")
    ms.wait(0.5)
    assert ms.cmd("M Z=0") == ACK
    ms.idle()
    ms.wait(1)
    assert ms.cmd("W Z") == b":A 0\r\n"


def test_first_listed_module_serves_both_kinds(make: Callable[..., Harness]) -> None:
    """MS-SI-3: with SEEK LIMITS listed first one `SI` still serves linear and rotary axes."""
    ms = make(ALL_MODULES, {"modules": ["SEEK LIMITS", "SEARCH INDEX"]})
    assert ms.cmd("SI X=7") == ACK
    ms.input("index_missing", axis="X")
    assert ms.cmd("SI Z=1") == ACK
    ms.idle()
    assert ms.cmd("SI X? Z?") == b":A X=7 Z=1\r\n"


def test_values_are_volatile(ms: Harness) -> None:
    """MS-SI-1, MS-112: the last values read 0 again after a reset."""
    ms.cmd("SI Y=300")
    ms.cmd("~")
    assert ms.cmd("SI X? Y?") == b":A X=0 Y=0\r\n"


def test_bad_items(ms: Harness) -> None:
    """MS-30, MS-31: no items `:N-3`, a letter that is no axis `:N-2`."""
    assert ms.cmd("SI") == b":N-3\r\n"
    assert ms.cmd("SI Q=1") == b":N-2\r\n"
