"""`stage-emu capture --device mp285` against the in-process emulator in virtual time: the status
block (MP-60), STEP fields (MP-63), XSPEED (MP-61), VERSION and the lone-CR reply (MP-20) come
back in a profile extending the closest bundled one; only `s` and a CR reach the device."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (stageemu:// URLs)
from emulator.profiles.profile import load_profile
from emulator.tools.capture import Capture, CaptureError, LineOptions, capture
from emulator.tools.capture.mp285 import plan
from emulator.tools.capture.run import capture_from
from emulator.urlhandler.hosted import serve
from emulator.urlhandler.url import VIRTUAL, UrlOptions
from tests.support.capture import Rewriting, mismatches, served_profile

#: an MP-285A whose stored setup differs from dump B: ROE_VARI 9, setup 3, firmware 3.03, 1000 µm/s
TEMPLATE = "63 03 01 01 09 00 14 00 63 00 05 00 88 13 01 78 C4 09 88 13 50 00 00 00 19 00 04 00 DC 05 2F 01"
CHANGES: dict[str, Any] = {
    "controller": {"status_template": TEMPLATE, "power_on_velocity_word": 1000},
    "knobs": {"stray_terminator_reply": "ignore"},
}
USB = LineOptions(rtscts=True)


def captured(source: str, tmp_path: Path, line: LineOptions = USB) -> tuple[Capture, Path]:
    result = capture(source, "mp285", line, 1.0)
    path = tmp_path / "captured.yaml"
    path.write_text(result.text)
    return result, path


def test_a_non_default_mp285a_comes_back_in_every_captured_field(tmp_path: Path) -> None:
    served = served_profile(tmp_path, "mp285a", **CHANGES)
    result, path = captured(f"stageemu://?profile={served}&time={VIRTUAL}", tmp_path)
    assert result.settled.parent.name == "mp285a"
    assert mismatches(result.settled.readings, served, path) == []
    controller = load_profile(str(path)).config.controller
    assert (controller.firmware_version, controller.power_on_velocity_word) == (303, 1000)
    assert sorted(r.dotted for r in result.settled.chosen) == [
        "controller.power_on_velocity_word",
        "controller.status_template",
        "knobs.stray_terminator_reply",
    ], "firmware_version follows the template's VERSION word: not written"
    assert result.notes == []
    assert (
        "# The model is not readable: mp285a's mp285a (low-resolution limit 3000 µm/s, MP-38)." in result.text
    )


@pytest.mark.parametrize(
    ("bundled", "line"),
    [
        ("mp285", LineOptions()),
        ("mp285-mt800", LineOptions()),
        ("mp285a-qr", USB),
        ("mp285a-rs232", LineOptions()),
    ],
)
def test_the_step_fields_and_interface_pick_the_bundled_profile(
    bundled: str, line: LineOptions, tmp_path: Path
) -> None:
    """MP-63: 25/4, 20/5 (MT-800) and 400/400 (the quick reference's format) tell the profiles
    apart; the interface is how the port was opened."""
    result, _ = captured(f"stageemu://{bundled}?time={VIRTUAL}", tmp_path, line)
    assert (result.settled.parent.name, result.settled.chosen) == (bundled, [])


def test_a_baud_rate_other_than_the_parents_is_written(tmp_path: Path) -> None:
    served = served_profile(tmp_path, "mp285", line={"baud": 19200, "stop_bits": 2})
    line = LineOptions(19200, stop_bits=2)
    result, path = captured(f"stageemu://?profile={served}&time={VIRTUAL}", tmp_path, line)
    assert mismatches(result.settled.readings, served, path) == []
    assert "line:\n  baud: 19200\n  stop_bits: 2\n" in result.text


def test_only_the_status_query_and_a_lone_cr_reach_the_device(tmp_path: Path) -> None:
    device = serve(UrlOptions(profile="mp285", time=VIRTUAL))
    records: list[dict[str, Any]] = []
    device.call(lambda: device.runner.watch_traffic(records.append))
    try:
        capture(device.url(), "mp285", LineOptions(), 1.0)
    finally:
        device.close()
    received = bytes.fromhex(" ".join(r["hex"] for r in records if r["dir"] == "rx"))
    assert received == b"".join(q.wire for q in plan()) == b"s\r\r"


def with_rewrites(source: str, rewrites: dict[bytes, Any]) -> Capture:
    port = serial.serial_for_url(source, baudrate=9600, timeout=1.0)
    try:
        return capture_from(Rewriting(port, rewrites), "mp285", LineOptions(), 1.0)
    finally:
        port.close()


def test_unknown_step_fields_and_an_odd_cr_reply_are_comments() -> None:
    def step_fields_7_9(reply: bytes) -> bytes:
        return reply[:24] + bytes([7, 0, 9, 0]) + reply[28:]

    result = with_rewrites(
        f"stageemu://mp285?time={VIRTUAL}", {b"s\r": step_fields_7_9, b"\r": lambda reply: b"4"}
    )
    assert result.notes == [
        "s: STEP_DIV/STEP_MUL 7/9 — not understood (neither device type in either format, MP-63)",
        "CR replied '34' — not understood",
    ]
    assert result.settled.parent.name == "mp285"
    assert result.settled.chosen == []


def test_no_reply_to_the_status_query_is_one_error(tmp_path: Path) -> None:
    """MS2000 at 115200 hears only garble from a 9600 host and answers nothing (MS-4)."""
    with pytest.raises(CaptureError, match=r"no reply to s at 9600 8N1 within 1.03 s: wrong port"):
        capture(f"stageemu://ms2000-ttlrep?time={VIRTUAL}", "mp285", LineOptions(), 1.0)
