"""`stage-emu capture --device ms2000` against the in-process emulator in virtual time: a capture of
a non-default profile reproduces it in every captured field (the issue's test), extends the
closest bundled profile and sets only what differs; only the dry-run's read-only lines reach the
device; replies not understood, and values no profile can hold, become comments."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import serial
import yaml

import emulator.urlhandler  # noqa: F401  (stageemu:// URLs)
from emulator.profiles.profile import load_profile
from emulator.tools.capture import Capture, LineOptions, capture
from emulator.tools.capture.ms2000 import is_read_only, plan
from emulator.tools.capture.readings import Query
from emulator.tools.capture.run import capture_from
from emulator.urlhandler.hosted import HostedDevice, serve
from emulator.urlhandler.url import VIRTUAL, UrlOptions
from tests.support.capture import Rewriting, mismatches, served_profile

#: a CRISP build whose unit differs from `ms2000-crisp` in identity, mechanics and reply knobs
CHANGES: dict[str, Any] = {
    "device_id": "served-0001",
    "version": "USB-9.2m",
    "who": "ASI-MS2000-XYBR-Zs-USB-LAB",
    "servo_ms": 5,
    "axes": {
        "X": {"speed_mm_s": 4.5, "backlash_mm": 0.02, "overshoot_mm": 0.05, "accel_ms": 90, "kp": 120},
        "Y": {"speed_mm_s": 3.25, "finish_error_mm": 0.000031, "maintain": 2, "input_device": 0},
        "Z": {"counts_per_mm": 25000, "soft_lower_mm": -5.5, "backlash_mm": 0, "ll_id": 30},
    },
    "knobs": {
        "version_trailing_space": False,
        "reply_shape_overrides": {"OS": "colon_axis_A", "PC": "colon_axis_A"},
        "reply_trailing_space": True,
        "info_fix_pc_tag": True,
        "empty_line_reply": "ignore",
        "info_absent_axis": "error",
        "rb_space_after_ack": True,
        "crisp_directive_name": "CRIFF",
        "bu_x_ring_buffer_size": False,
    },
}


def url(path: Path) -> str:
    return f"stageemu://?profile={path}&time={VIRTUAL}"


def captured(source: str, tmp_path: Path, name: str = "captured", baud: int = 9600) -> tuple[Capture, Path]:
    result = capture(source, "ms2000", LineOptions(baud), 1.0, name)
    path = tmp_path / f"{name}.yaml"
    path.write_text(result.text)
    return result, path


def test_a_non_default_profile_comes_back_in_every_captured_field(tmp_path: Path) -> None:
    served = served_profile(tmp_path, "ms2000-crisp", **CHANGES)
    result, path = captured(url(served), tmp_path)
    assert result.notes == []
    assert load_profile(str(path)).chain[-2].endswith("ms2000-crisp.yaml")
    assert mismatches(result.settled.readings, served, path) == []
    fields = {r.dotted for r in result.settled.readings if r.captured}
    assert {"version", "axes.X.speed_mm_s", "axes.Z.counts_per_mm", "knobs.info_absent_axis"} <= fields


def test_only_what_differs_from_the_parent_is_written(tmp_path: Path) -> None:
    served = served_profile(tmp_path, "ms2000-crisp", **CHANGES)
    result, path = captured(url(served), tmp_path, "lab-stage")
    assert result.notes == []
    data = yaml.safe_load(path.read_text())
    assert data["extends"] == "ms2000-crisp" and data["device_id"] == "lab-stage"
    assert data["axes"]["X"] == {"speed_mm_s": 4.5, "accel_ms": 90, "backlash_mm": 0.02, "kp": 120,
                                 "overshoot_mm": 0.049983}  # fmt: skip
    # Z's finish error follows its new encoder resolution (a derived default): not written
    assert data["axes"]["Z"] == {
        "counts_per_mm": 25000.0,
        "soft_lower_mm": -5.5,
        "backlash_mm": 0.0,
        "ll_id": 30,
    }
    assert data["knobs"]["reply_shape_overrides"] == {"OS": "colon_axis_A", "PC": "colon_axis_A"}
    assert "modules" not in data and "build_name" not in data and "dip_switches" not in data
    assert path.read_text().startswith("# Captured by `stage-emu capture --device ms2000` from stageemu://")


@pytest.mark.parametrize("bundled", ["ms2000", "ms2000-xy", "ms2000-seq", "ms2000-ttlrep", "ms2000-pz-crisp"])
def test_a_bundled_profile_is_its_own_closest_and_nothing_else_is_set(bundled: str, tmp_path: Path) -> None:
    baud = load_profile(bundled).config.line.baud
    result, _ = captured(f"stageemu://{bundled}?time={VIRTUAL}", tmp_path, baud=baud)
    assert result.settled.parent.name == bundled
    assert [r.dotted for r in result.settled.chosen] == ["device_id"]
    assert result.notes == []


@pytest.fixture
def hosted(tmp_path: Path) -> Iterator[HostedDevice]:
    device = serve(UrlOptions(profile=str(served_profile(tmp_path, "ms2000-crisp", **CHANGES)), time=VIRTUAL))
    yield device
    device.close()


def test_the_device_receives_exactly_the_dry_run_lines(hosted: HostedDevice, tmp_path: Path) -> None:
    records: list[dict[str, Any]] = []
    hosted.call(lambda: hosted.runner.watch_traffic(records.append))
    capture(hosted.url(), "ms2000", LineOptions(), 1.0)
    received = bytes.fromhex(" ".join(r["hex"] for r in records if r["dir"] == "rx"))
    assert received == b"".join(q.wire for q in plan())
    lines = received.split(b"\r")[:-1]
    assert all(is_read_only(Query(line.decode(), line + b"\r")) for line in lines)


@pytest.mark.parametrize(
    "line",
    ["M X=1", "R X=1", "S X=1", "SS Z", "SS X", "~", "\\", "HALT", "SP", "Z", "Z X?", "EX M?", "BU Y=65",
     "BU Z+", "H X=0", "AZ X", "I", "RB", "V X=1", "CD X=1", "SB X=2", "S X? Y=2", "LED X=0", "\xffB"],
)  # fmt: skip
def test_nothing_that_moves_sets_saves_or_resets_passes_the_read_only_check(line: str) -> None:
    query = Query(line, line.encode("latin-1") + b"\r")
    assert not is_read_only(query)


def test_every_planned_line_passes_the_read_only_check() -> None:
    assert all(is_read_only(q) for q in plan())


def test_a_reply_not_understood_is_a_comment_and_its_field_stays_the_parents(tmp_path: Path) -> None:
    """A knob that turns KP's reply bare: the capture cannot read it, says so, and goes on."""
    served = served_profile(
        tmp_path, "ms2000", axes={"X": {"kp": 120}}, knobs={"reply_shape_overrides": {"KP": "bare"}}
    )
    result, path = captured(url(served), tmp_path)
    assert result.notes == ["KP X? Y? Z? replied '120 100 500' — not understood"]
    assert "# - KP X? Y? Z? replied '120 100 500' — not understood" in path.read_text().splitlines()
    assert "kp" not in yaml.safe_load(path.read_text()).get("axes", {}).get("X", {})
    assert load_profile(str(path)).config.axes["X"].kp == 100


def with_rewrites(source: str, rewrites: dict[bytes, Any]) -> Capture:
    port = serial.serial_for_url(source, baudrate=9600, timeout=1.0)
    try:
        return capture_from(Rewriting(port, rewrites), "ms2000", LineOptions(), 1.0)
    finally:
        port.close()


def test_odd_replies_are_comments_never_guesses() -> None:
    def extra_module(reply: bytes) -> bytes:
        return reply.replace(b"\r\n", b"\rFANCY MODULE\r\n")

    result = with_rewrites(
        f"stageemu://ms2000?time={VIRTUAL}",
        {
            b"V\r": lambda reply: b":A Version: \x01\r\n",
            b"BU X\r": extra_module,
            b"SB X?\r": lambda reply: b":A X=3\r\n",
            b"CD\r": lambda reply: b"",
        },
    )
    assert result.notes == [
        "V replied ':A Version: \\x01' — not understood",
        "BU X lists the module 'FANCY MODULE', which stage-emu does not emulate: left out",
        "CD: no reply within 1.08 s",
        "SB X? gave line.stop_bits 3: 3 is not one of 1, 2",
    ]
    chosen = {r.dotted for r in result.settled.chosen}
    assert chosen == {"device_id"}, "nothing odd is written; the rest matches ms2000"
    assert "# - SB X? gave line.stop_bits 3: 3 is not one of 1, 2" in result.text.splitlines()


def test_a_speed_above_the_parents_maximum_raises_the_maximum(tmp_path: Path) -> None:
    """MS-54: a 12.7 mm lead screw allows 15.36 mm/s; the capture cannot read the pitch."""
    served = served_profile(tmp_path, "ms2000", axes={"X": {"pitch_mm": 12.7, "speed_mm_s": 10}})
    result, path = captured(url(served), tmp_path)
    assert result.notes == [
        "S X? Y? Z?: X runs at 10 mm/s, above ms2000's maximum 7.68: max_speed_mm_s raised to it "
        "(the real maximum is not readable)"
    ]
    axis = load_profile(str(path)).config.axes["X"]
    assert (axis.speed_mm_s, axis.max_speed_mm_s) == (10.0, 10.0)
