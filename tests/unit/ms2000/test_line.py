"""Line assembly and line settings on the model (§1, §2.1): what the port does not show. The vectors
of §1 and §2 (TV-1…TV-10, TV-90, TV-116…TV-121) run in tests/conformance/ms2000."""

from __future__ import annotations

from collections.abc import Callable

from emulator.device import LineSettings
from tests.unit.ms2000.conftest import Harness

VERSION = b":A Version: USB-9.2k \r\n"


def test_byte_by_byte_equals_one_chunk_ms6(ms: Harness) -> None:
    assert ms.send(b"/\rV\rW X Y\r", chunk=1) == b"N\r\n" + VERSION + b":A 0 0\r\n"


def test_device_stop_bits_and_mismatch_wording_ms3_ms4(ms: Harness, make: Callable[..., Harness]) -> None:
    """What the port does not show: `SB X=2` sets the device's own line to 2 stop bits, and the
    line the daemon logs for a host at other settings calls 1 stop bit harmless, another baud
    rate garbled and, with `line_mismatch: ignore`, any difference ignored."""
    ms.cmd("SB X=2")
    assert ms.dev.line_settings().stop_bits == 2
    assert "harmless" in ms.dev.mismatch_effect(LineSettings(baud=9600, stop_bits=1))
    assert "garbled" in ms.dev.mismatch_effect(LineSettings(baud=19200))
    lenient = make(overrides={"knobs": {"line_mismatch": "ignore"}})
    assert "ignored" in lenient.dev.mismatch_effect(LineSettings(baud=115200))


def test_junk_dropped_when_settings_match_again_ms4(ms: Harness) -> None:
    """Half a garbled line, whether ASCII or a low-level frame, is dropped once the host's settings
    match again (MS-4)."""
    ms.dev.line_changed(LineSettings(baud=19200), ms.t)
    ms.send(b"W X")
    ms.dev.line_changed(LineSettings(baud=9600), ms.t)
    assert ms.cmd("V") == VERSION
    ms.send(b"\xffB")
    ms.dev.line_changed(LineSettings(baud=19200), ms.t)
    ms.send(b"\x18a")
    ms.dev.line_changed(LineSettings(baud=9600), ms.t)
    assert ms.send(b"\x18a\x03:") == bytes(3)


def test_garble_junk_is_never_cr_nor_ff_ms4() -> None:
    from emulator.devices.ms2000.model import garble

    junk = garble(bytes(range(256)))
    assert 0x0D not in junk and 0xFF not in junk
    assert junk[0x58] == 0x0E and junk[0xAA] == 0xFE


def test_garble_model_both_directions_ms4(ms: Harness) -> None:
    ms.dev.line_changed(LineSettings(baud=19200), ms.t)
    ms.dev.receive(b"V\r", ms.t)
    assert ms.dev.take_output() == []
    ms.input("log_error", code=1)
    ms.dev.line_changed(LineSettings(baud=9600), ms.t)
    assert ms.cmd("") == b":N-1\r\n"
    ms.dev.line_changed(LineSettings(baud=19200), ms.t)
    ms.input("ttl_in1", level=1)
    ms.dev.line_changed(None, ms.t)
    ms.cmd("VB X=4")
    ms.dev.line_changed(LineSettings(baud=19200), ms.t)
    ms.input("ttl_in1", level=0)
    junk = ms.output()
    assert junk == bytes([ord("L") ^ 0x55, 0x0D ^ 0x55, 0x0A ^ 0x55])
    assert b"\r" not in junk and b"\xff" not in junk


def test_transport_sees_baud_declaration_keeps_parity_ms4(ms: Harness) -> None:
    ms.input("host_line", parity="even")
    ms.dev.line_changed(LineSettings(baud=9600), ms.t)
    assert ms.get("host_line") == "9600 ?E? (data bits, stop bits not visible)"
    ms.dev.line_changed(None, ms.t)
    assert ms.get("host_line") is None
