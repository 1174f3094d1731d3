"""Line assembly, replies, terminators and line settings (§1, §2.1, §2.2): TV-1…TV-10, TV-90,
TV-116…TV-120."""

from __future__ import annotations

from collections.abc import Callable

from emulator.device import LineSettings
from tests.unit.ms2000.conftest import Harness

VERSION = b":A Version: USB-9.2k \r\n"


def test_tv_001_version_ms99_ms6_ms14_ms11(ms: Harness) -> None:
    assert ms.cmd("V") == VERSION


def test_tv_002_case_insensitive_ms10(ms: Harness) -> None:
    assert ms.cmd("v") == VERSION
    assert ms.cmd("s x?") == b":A X=5.145600\r\n"


def test_tv_003_empty_line_ms8(ms: Harness) -> None:
    assert ms.send(b"\r") == b":N-1\r\n"


def test_tv_004_empty_line_ignored_ms8(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"empty_line_reply": "ignore"}})
    assert h.send(b"\r") == b""
    assert h.cmd("/") == b"N\r\n"


def test_tv_005_crlf_host_ms7_ms100(ms: Harness) -> None:
    assert ms.send(b"V\r\nCD\r") == VERSION + b"Mar 14 2016:17:32:08\r\n"


def test_tv_006_lf_cr_is_blank_line_ms7_ms8(ms: Harness) -> None:
    assert ms.send(b"\n\r") == b":N-1\r\n"


def test_tv_007_overlong_line_ms9(ms: Harness) -> None:
    assert ms.send(b"A" * 300 + b"\r") == b":N-6\r\n"
    assert ms.cmd("/") == b"N\r\n"


def test_tv_007_overlong_line_byte_by_byte_ms9(ms: Harness) -> None:
    assert ms.send(b"W X" + b" " * 400 + b"\r", chunk=1) == b":N-6\r\n"


def test_tv_008_unknown_and_split_words_ms19(ms: Harness) -> None:
    assert ms.cmd("FOO X=1") == b":N-1\r\n"
    assert ms.cmd("MOVEREL X=0") == b":A\r\n"
    assert ms.cmd("!X") == b":A\r\n"


def test_tv_009_control_character_in_word_ms12(ms: Harness) -> None:
    assert ms.send(b"V\x01\r") == b":N-1\r\n"


def test_tv_010_two_lines_one_write_ms13_ms32_ms78(ms: Harness) -> None:
    assert ms.send(b"/\rV\r") == b"N\r\n" + VERSION


def test_byte_by_byte_equals_one_chunk_ms6(ms: Harness) -> None:
    assert ms.send(b"/\rV\rW X Y\r", chunk=1) == b"N\r\n" + VERSION + b":A 0 0\r\n"


def test_tv_090_cr_only_terminators_from_next_reply_ms16(ms: Harness) -> None:
    assert ms.cmd("VB X=8") == b":A\r\n"
    assert ms.cmd("/") == b"N\r"
    assert ms.cmd("BU") == b"STD_XYZ\r"
    assert ms.cmd("VB X=0") == b":A\r"
    assert ms.cmd("/") == b"N\r\n"


def test_tv_116_stop_bits_never_garble_ms3_ms4(ms: Harness) -> None:
    assert ms.cmd("SB X?") == b":A X=1\r\n"
    assert ms.cmd("SB X=3") == b":N-4\r\n"
    assert ms.cmd("SB X=2") == b":A\r\n"
    assert ms.dev.line_settings().stop_bits == 2
    ms.dev.line_changed(LineSettings(baud=9600, stop_bits=1), ms.t)
    assert ms.cmd("V") == VERSION
    assert "harmless" in ms.dev.mismatch_effect(LineSettings(baud=9600, stop_bits=1))


def test_tv_117_dip_baud_and_garble_ms2_ms4(ms: Harness) -> None:
    ms.input("dip", sw4="down", sw5="down")
    ms.input("power_cycle")
    assert ms.get("baud") == 115200
    ms.input("host_line", baud=115200)
    assert ms.cmd("V") == VERSION
    ms.input("host_line", baud=9600)
    assert ms.cmd("V") == b""
    assert "garbled" in ms.dev.mismatch_effect(LineSettings(baud=9600))


def test_tv_118_dips_read_at_power_up_only_ms2(ms: Harness) -> None:
    ms.input("dip", sw4="down", sw5="up")
    ms.input("power_cycle")
    assert ms.get("baud") == 19200
    ms.input("dip", sw4="up", sw5="down")
    ms.input("host_line", baud=19200)
    assert ms.cmd("V") == VERSION
    ms.input("power_cycle")
    assert ms.get("baud") == 28800


def test_tv_119_mismatch_ignored_ms4(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"line_mismatch": "ignore"}})
    h.input("host_line", baud=115200)
    assert h.cmd("V") == VERSION
    assert "ignored" in h.dev.mismatch_effect(LineSettings(baud=115200))


def test_tv_120_data_bits_and_parity_ms1_ms4(ms: Harness) -> None:
    ms.input("host_line", baud=9600, data_bits=7, parity="even")
    assert ms.cmd("V") == b""
    ms.input("host_line", baud=9600, data_bits=8, parity="none")
    assert ms.cmd("V") == VERSION  # the junk of the garbled line does not prefix it


def test_junk_dropped_when_settings_match_again_ms4(ms: Harness) -> None:
    """Half a garbled line, whether ASCII or a low-level frame, is dropped once the host's settings
    match again (TV-120)."""
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
