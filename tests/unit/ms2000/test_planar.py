"""PLANAR CORRECTION (§9.9) on the manual clock: the rest of MS-PC-1…MS-PC-5 beyond the test vectors,
which run in tests/conformance/ms2000 (TV-187…TV-192).

The build is profile `ms2000-seq` (X and Y on linear encoders at 100000 counts/mm).
"""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.modules.planar import fit
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def run(h: Harness, *commands: str) -> None:
    """Each command acknowledged, then (idle)."""
    for command in commands:
        assert h.cmd(command) == ACK, command
    h.idle()


@pytest.fixture
def seq() -> Harness:
    return Harness("ms2000-seq")


@pytest.fixture
def plane(seq: Harness) -> Harness:
    """The vectors' plane: points (0, 0, 0), (10, 0, 0), (0, 10, 0.01) mm; enabled at the third."""
    run(seq, "CCB Z=1", "M X=100000")
    run(seq, "CCB Z=2", "M X=0 Y=100000 Z=100")
    run(seq, "CCB Z=3", "CCB Z=4")
    return seq


def z_counts(h: Harness) -> int:
    return int(h.get("axes")["Z"]["machine_counts"])


def test_z_follows_along_the_way_ms_pc_2(plane: Harness) -> None:
    """MS-PC-2: the correction follows Y continuously, mid-move included, at 1 µm per mm."""
    assert plane.cmd("M Y=0") == ACK
    plane.wait(0.5)
    axes = plane.get("axes")
    y_mm = axes["Y"]["user_mm"]
    assert 0.0 < y_mm < 10.0
    assert axes["Z"]["machine_counts"] == pytest.approx(y_mm * 0.001 * 20000, abs=1)
    assert plane.cmd("W Z") == b":A 0\r\n"
    plane.idle()
    assert z_counts(plane) == 0


def test_joystick_moves_follow_the_plane_ms_pc_2(plane: Harness) -> None:
    """MS-PC-2: manual XY motion is corrected too."""
    before = z_counts(plane)
    plane.input("joystick", x=0.0, y=-1.0)
    plane.wait(0.5)
    plane.input("joystick", x=0.0, y=0.0)
    y_mm = plane.get("axes")["Y"]["user_mm"]
    assert y_mm < 10.0
    assert z_counts(plane) == pytest.approx(before - (10.0 - y_mm) * 20, abs=1)


def test_enable_and_disable_never_move_z_ms_pc_2(plane: Harness) -> None:
    """MS-PC-2: switching re-expresses the commanded position; the physical one stays."""
    run(plane, "M Y=50000")
    physical = z_counts(plane)
    assert plane.cmd("CCB Z=5") == ACK
    assert z_counts(plane) == physical
    assert plane.cmd("W Z") == b":A 50\r\n"
    assert plane.cmd("CCB Z=4") == ACK
    assert z_counts(plane) == physical
    assert plane.cmd("W Z") == b":A 0\r\n"


def test_info_reports_the_physical_target_ms_pc_2(plane: Harness) -> None:
    """MS-PC-2: INFO's "enc target" includes the correction, "Target pos" does not."""
    report = plane.cmd("I Z").decode()
    assert "Target pos   :    0.0000 (mm)" in report
    assert "enc target   :       200" in report


def test_collinear_points_fit_no_plane_ms_pc_1(seq: Harness) -> None:
    """MS-PC-1: three points on one line in XY are refused."""
    run(seq, "CCB Z=1", "M X=10000")
    run(seq, "CCB Z=2", "M X=20000 Z=50")
    assert seq.cmd("CCB Z=3") == ACK
    assert seq.cmd("CCB Z=4") == b":N-5\r\n"
    assert fit([(0, 0, 0), (1, 1, 0), (2, 2, 1)]) is None
    assert fit([(0, 0, 0), (1, 0, 0.5), (0, 2, 1)]) == (0.5, 0.5)


def test_home_needs_3_s_without_ring_buffer_ms_pc_4() -> None:
    """MS-PC-4: without RING BUFFER, home held 3 s disables."""
    h = Harness("ms2000-seq", {"modules": ["LL COMMANDS", "INO_INT", "PLANAR CORRECTION"]})
    run(h, "CCB Z=1", "M X=100000")
    run(h, "CCB Z=2", "M X=0 Y=100000")
    run(h, "CCB Z=3", "CCB Z=4")
    h.input("button", name="home", ms=3000)
    h.wait(3.0)
    assert h.get("planar")["state"] == "G"


def test_unsaved_plane_is_gone_after_reset_ms_pc_5(plane: Harness) -> None:
    """MS-PC-5: without `SS Z` a reset brings back the factory state: no correction, so Z's
    physical position is its commanded one again."""
    assert plane.cmd("~") == ACK
    assert plane.get("planar")["state"] == "1"
    axes = plane.get("axes")
    assert axes["Z"]["machine_counts"] == axes["Z"]["target_counts"]
    assert plane.dev.axes[2].follow is None


def test_here_changes_the_offset_not_the_tilt_ms_pc_2(plane: Harness) -> None:
    """MS-PC-2: `H Y` shifts the plane's height here by tilt × shift; its tilt stays."""
    run(plane, "M Y=50000")
    assert plane.cmd("CCB Z=6") == b":A 50\r\n"
    assert plane.cmd("H Y=0") == ACK
    assert plane.cmd("CCB Z=6") == b":A 0\r\n"
    assert plane.get("planar")["b"] == pytest.approx(0.001)
    run(plane, "M Y=50000")
    assert plane.cmd("CCB Z=6") == b":A 50\r\n"


def test_button_functions_13_and_14_ms_86(seq: Harness) -> None:
    """Appendix B: `BE F` functions 13 (select point) and 14 (disable/reset) exist."""
    assert seq.dev.buttons.valid_function(13)
    seq.dev.buttons.run_function(13, seq.t)
    assert seq.get("planar")["state"] == "2"
    seq.dev.buttons.run_function(14, seq.t)
    assert seq.get("planar")["state"] == "1"
