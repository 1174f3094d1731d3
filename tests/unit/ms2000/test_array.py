"""ARRAY MODULE (§9.1) on the manual clock: the rules around the test vectors, which run in
tests/conformance/ms2000 (TV-129…TV-138).

These run on profile `ms2000-seq`, where SEQUENCER sits beside ARRAY (without a program it leaves
`@` to ARRAY, MS-85)."""

from __future__ import annotations

import itertools
from typing import Any

import pytest

from emulator.devices.ms2000.modules.array import CellOrder
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def seq(**knobs: Any) -> Harness:
    return Harness("ms2000-seq", {"knobs": knobs} if knobs else None)


@pytest.fixture
def arr() -> Harness:
    return seq()


@pytest.fixture
def two_by_two(arr: Harness) -> Harness:
    """The 2×2 array the vectors use: 1 mm apart, 50 ms dwell."""
    assert arr.cmd("AR X=2 Y=2 Z=1 F=1") == ACK
    assert arr.cmd("RT Z=50") == ACK
    return arr


def arrivals(h: Harness) -> list[tuple[int, int]]:
    return [(e["i"], e["j"]) for e in h.take_events("array_arrival")]


def run_out(h: Harness, seconds: float = 10.0, step: float = 0.005) -> str:
    """Let `seconds` pass; the array states seen, one per change."""
    seen = ""
    for _ in range(round(seconds / step)):
        h.wait(step)
        state = h.get("array")["state"]
        if not seen or seen[-1] != state:
            seen += state
    return seen


def test_aij_missing_item_keeps_the_last_one_ms_array_4(arr: Harness) -> None:
    """MS-ARRAY-4: a missing item keeps the last i or j (1,1 initially)."""
    arr.cmd("AIJ Y=2")
    arr.idle()
    assert arr.cmd("AIJ X? Y?") == b":A X=1 Y=2\r\n"
    arr.cmd("AIJ X=3")
    arr.idle()
    assert arr.cmd("W X Y") == b":A 180000 -90000\r\n"


def test_sn_swaps_the_axes_of_columns_and_rows_ms_array_3(arr: Harness) -> None:
    """MS-ARRAY-3: with `SN X=2 Y=1` the columns run along Y and the rows along X."""
    assert arr.cmd("SN X=2 Y=1") == ACK
    arr.cmd("AIJ X=2 Y=3")
    arr.idle()
    assert arr.cmd("W X Y") == b":A -180000 90000\r\n"


def test_self_scan_dwell_is_rt_z_ms_array_5(two_by_two: Harness) -> None:
    """MS-ARRAY-5: the next move starts `RT Z` ms after each arrival."""
    two_by_two.cmd("RT Z=400")
    two_by_two.cmd("AR")
    two_by_two.settle()
    events = [e for e in two_by_two.take_events() if e["ev"] in ("array_arrival", "move_complete")]
    arrived = [e["t"] for e in events if e["ev"] == "array_arrival"]
    assert len(arrived) == 4
    assert two_by_two.get("array")["state"] == "I"
    for earlier, later in itertools.pairwise(arrived):
        assert later - earlier > 0.4


def test_bare_ar_stops_a_self_scan_and_halt_too_ms_array_5(two_by_two: Harness) -> None:
    """MS-ARRAY-5: `AR` while a scan runs stops it; HALT stops it (state I)."""
    two_by_two.cmd("RT Z=1000")
    two_by_two.cmd("AR")
    two_by_two.idle()
    two_by_two.wait(0.1)
    assert two_by_two.get("array")["state"] == "D"
    assert two_by_two.cmd("AR") == ACK
    assert two_by_two.get("array")["state"] == "I"
    two_by_two.wait(2)
    assert arrivals(two_by_two) == [(1, 1)]
    two_by_two.cmd("M X=5000")
    two_by_two.idle()
    two_by_two.cmd("AR")
    assert two_by_two.cmd("\\") == b":N-21\r\n"
    two_by_two.settle()
    assert two_by_two.get("array")["state"] == "I"
    assert arrivals(two_by_two) == []


def test_ring_buffer_mode_3_repeats_the_self_scan_ms_array_5(two_by_two: Harness) -> None:
    """MS-ARRAY-5: with `RM F=3` the array starts over after the last cell until stopped."""
    two_by_two.cmd("RM F=3")
    two_by_two.cmd("AR")
    run_out(two_by_two, 6.0)
    visited = arrivals(two_by_two)
    assert visited[:6] == [(1, 1), (2, 1), (2, 2), (1, 2), (1, 1), (2, 1)]
    assert two_by_two.get("array")["running"] == "self_scan"
    two_by_two.cmd("AR")
    assert two_by_two.get("array")["state"] == "I"


def test_at_button_and_be_f7_start_a_self_scan_ms_array_5(two_by_two: Harness) -> None:
    """MS-ARRAY-5: a normal `@` press starts the self-scan; BE F=7 (Appendix B) stops it."""
    two_by_two.input("button", name="at", ms=200)
    two_by_two.wait(0.3)
    assert two_by_two.get("array")["running"] == "self_scan"
    assert two_by_two.cmd("BE F=7") == ACK
    assert two_by_two.get("array")["running"] is None


def test_stepping_ignores_triggers_while_moving_lower_case_ms_array_7(two_by_two: Harness) -> None:
    """MS-ARRAY-7: while a stepping move runs IN0 is ignored and the state shows in lower case;
    a bare `RM` is a trigger too (MS-RB-5)."""
    two_by_two.cmd("TTL X=7")
    two_by_two.cmd("RM X=1")
    two_by_two.idle()
    assert two_by_two.cmd("RM") == ACK
    assert two_by_two.get("array")["state"] == "m"
    two_by_two.input("ttl_in0", pulse_ms=1)
    two_by_two.idle()
    assert two_by_two.get("array")["state"] == "A"
    assert arrivals(two_by_two) == [(1, 1), (2, 1)]


def test_rm_x1_without_array_is_out_of_range_ms_rb_4(ms: Harness) -> None:
    """MS-RB-4: `RM X=1` needs ARRAY MODULE."""
    assert ms.cmd("RM X=1") == b":N-4\r\n"


def test_cell_beyond_a_limit_is_error_ms_array_7(arr: Harness) -> None:
    """MS-ARRAY-7: a move stopped at a limit ends in state E."""
    arr.cmd("AR Z=70")
    arr.cmd("AIJ X=2 Y=1")
    arr.idle()
    assert arr.get("array")["state"] == "E"


def test_grid_home_and_roles_saved_with_ss_z_ms_array_1(arr: Harness) -> None:
    """MS-ARRAY-1, MS-ARRAY-2, MS-SCAN-1: AR, AH and SN survive a power cycle after `SS Z`."""
    arr.cmd("AR X=3 Y=4 Z=2 F=-2 T=5")
    arr.cmd("AH X=1.5 Y=-1")
    arr.cmd("SN X=2 Y=1 F=0")
    assert arr.cmd("SS Z") == ACK
    arr.input("power_cycle")
    assert arr.cmd("AR X? Y? Z? F? T?") == b":A X=3 Y=4 Z=2.000000 F=-2.000000 T=5.000000\r\n"
    assert arr.cmd("AH X? Y?") == b":A X=1.500000 Y=-1.000000\r\n"
    assert arr.cmd("SN X? Y? F?") == b":A X=2 Y=1 F=0\r\n"


def test_bare_sn_without_scan_module_ms_scan_1(arr: Harness) -> None:
    """MS-SCAN-1: an ARRAY-only build has SN settings but nothing to start [choice]: `:N-3`."""
    assert arr.cmd("SN") == b":N-3\r\n"
    assert arr.cmd("SN X=3") == b":N-4\r\n"


def test_cell_order_is_computed_per_step_ms_array_5() -> None:
    """MS-ARRAY-5: the visiting order of the largest grid is arithmetic, not a list of a million
    cells; serpentine reverses every second row, raster does not."""
    order = CellOrder(1000, 1000, serpentine=True)
    assert order.count == 1_000_000
    assert [order.cell(k) for k in (0, 999, 1000, 1999, 2000)] == [
        (1, 1),
        (1000, 1),
        (1000, 2),
        (1, 2),
        (1, 3),
    ]
    assert CellOrder(3, 2, serpentine=False).cell(3) == (1, 2)
    big = seq()
    big.cmd("AR X=1000 Y=1000 Z=0.001 F=0.001")
    assert big.cmd("AR") == ACK
    assert big.get("array")["running"] is not None
