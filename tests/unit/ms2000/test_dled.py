"""DLED, the two-channel current LED driver (§9.8), on the manual clock: MS-LED-4 and MS-LED-5
beyond the test vectors, which run in tests/conformance/ms2000 (TV-185, TV-186)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def dled() -> Harness:
    return Harness("ms2000-dled")


def lit(h: Harness) -> tuple[int, int]:
    led = h.get("led")
    return led["x"], led["y"]


def test_bad_values_change_nothing_ms_led_4(dled: Harness) -> None:
    """MS-LED-4: every letter 0–100; Z and F are no DLED letters; a bad item refuses the command."""
    dled.cmd("LED X=20")
    assert dled.cmd("LED X=101") == b":N-4\r\n"
    assert dled.cmd("LED X=30 R=-1") == b":N-4\r\n"
    assert dled.cmd("LED Z=1") == b":N-2\r\n"
    assert dled.cmd("LED") == b":N-3\r\n"
    assert dled.cmd("LED X? R?") == b"X=20 R=100 :A\r\n"


def test_bu_x_line_and_lcd_segment(dled: Harness) -> None:
    """MS-LED-4 / MS-102: `BU X` lists `DLED`; §9.0: LCD segment `L xx`."""
    assert dled.cmd("BU X").removesuffix(b"\r\n").split(b"\r")[-1] == b"DLED"
    dled.cmd("LED X=42")
    assert "L 42" in dled.get("lcd")[1]


def test_maxima_remembered_levels_saved_by_ss_z_ms_111(tmp_path: Path) -> None:
    """MS-111: the maxima are stored as soon as they change, the levels only by `SS Z`."""
    first = Harness("ms2000-dled", state_dir=tmp_path)
    first.cmd("LED R=40 T=60")
    first.cmd("LED X=30")
    first.input("power_cycle")
    assert first.cmd("LED X? R? T?") == b"X=0 T=60 R=40 :A\r\n"
    first.cmd("LED X=90 Y=20")
    assert first.cmd("SS Z") == ACK
    first.cmd("LED R=25")
    second = Harness("ms2000-dled", state_dir=tmp_path)
    assert second.cmd("LED X? Y? R?") == b"X=25 Y=20 R=25 :A\r\n", "the saved level is limited too"


@pytest.mark.parametrize(("mode", "first", "second"), [(22, (30, 60), (30, 60)), (23, (30, 0), (0, 60))])
def test_modes_22_23_light_while_in0_is_high_ms_led_5(
    dled: Harness, mode: int, first: tuple[int, int], second: tuple[int, int]
) -> None:
    """MS-LED-5: modes 22 and 23 are 20 and 21 lit until IN0 falls, however long that is."""
    dled.cmd("LED X=30 Y=60")
    dled.cmd(f"TTL X={mode}")
    dled.cmd("RT Y=10")
    dled.input("ttl_in0", level=1)
    dled.wait(0.5)
    assert lit(dled) == first
    dled.input("ttl_in0", level=0)
    assert lit(dled) == (0, 0)
    dled.input("ttl_in0", pulse_ms=300)
    dled.wait(0.29)
    assert lit(dled) == second
    dled.wait(0.02)
    assert lit(dled) == (0, 0)


def test_modes_need_ino_int_ms_90() -> None:
    """MS-90: IN0 modes 20–23 exist only with DLED (and INO_INT)."""
    assert Harness().cmd("TTL X=20") == b":N-4\r\n"
    assert Harness("ms2000-dled").cmd("TTL X=23") == ACK
