"""The traffic log tells what the device made of the bytes, taken from the model (design rule 11):
records per unit of input (`frame`, `garbled`, `lost`, `stray`), replies naming the command they
answer, and what the runner itself drops. Every device here runs under the real DeviceRunner on a
manual clock, with realistic pacing unless a test says otherwise."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import SNIFF_BYTES, NotATrafficLog, TrafficLog
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST, REALISTIC, char_time
from protocols import mp285
from tests.support.memory_transport import MemoryTransport
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)

CHAR = char_time(9600)
AT_9600 = LineSettings(9600, None, None, 1, False, False)
AT_19200 = LineSettings(19200, None, None, 1, False, False)


@dataclass
class Logged:
    clock: ManualClock
    runner: DeviceRunner
    port: MemoryTransport
    path: Path
    traffic: TrafficLog

    def records(self, **match: str) -> list[dict[str, Any]]:
        """The records written so far (those with the given field values); device events (`dir`
        `ev`) only when asked for by `dir="ev"`."""
        entries = [json.loads(line) for line in self.path.read_text().splitlines()]
        if "dir" not in match:
            entries = [e for e in entries if e["dir"] != "ev"]
        return [e for e in entries if all(e.get(k) == v for k, v in match.items())]

    def trickle(self, data: bytes, gap: float) -> None:
        """The host writes one byte every `gap` seconds (Micro-Manager's serial manager)."""
        for byte in data:
            self.port.send(bytes((byte,)))
            self.clock.advance(gap)


def logged(
    tmp_path: Path, profile: str, host: LineSettings = AT_9600, timing: str = REALISTIC, **over: Any
) -> Logged:
    clock = ManualClock()
    loaded = load_profile(profile, over or None)
    path = tmp_path / "traffic.jsonl"
    traffic = TrafficLog(path)
    name = loaded.family
    runner = DeviceRunner(
        lambda now: family(name).factory("dut", loaded, now, DeviceServices()),  # type: ignore[union-attr]
        clock,
        traffic=traffic,
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(host)
    return Logged(clock, runner, port, path, traffic)


def kinds(records: list[dict[str, Any]]) -> list[tuple[str, str]]:
    return [(r["dir"], r["kind"]) for r in records]


# ---- MP-285 --------------------------------------------------------------------------------------


def test_mp285_move_written_a_byte_per_ms_is_one_frame_and_its_reply_names_it(tmp_path: Path) -> None:
    """MP-8: a 14-byte `m` frame trickled in one byte per millisecond is one command; MP-47: its `0D`
    comes when the move has ended and answers the `m`."""
    log = logged(tmp_path, "mp285")
    move = mp285.Move(2500, 0, 0)
    log.trickle(move.encode(), 0.001)
    log.clock.advance(2.0)
    assert log.port.take() == b"\r"
    records = log.records()
    assert kinds(records) == [("rx", "frame"), ("tx", "reply")]
    frame, reply = records
    assert frame["hex"] == move.encode().hex(" ") and frame["summary"] == "m X=2500 Y=0 Z=0 (µsteps)"
    assert reply["summary"] == "reply to m X=2500 Y=0 Z=0 (µsteps): CR (done)"
    assert frame["t"] < reply["t"]


def test_mp285_query_reply_names_its_command(tmp_path: Path) -> None:
    """MP-35: the position reply is logged once, with its last byte, as the answer to `c`."""
    log = logged(tmp_path, "mp285")
    log.port.send(b"c\r")
    log.clock.advance(20 * CHAR)
    assert len(log.port.take()) == mp285.POSITION_REPLY_LENGTH
    (reply,) = log.records(dir="tx")
    assert reply["summary"] == "reply to c: position X=0 Y=0 Z=0 (µsteps)"
    assert reply["t"] == round(15 * CHAR, 6)  # 2 characters in, 13 out


def test_mp285_bytes_at_a_mismatched_baud_are_logged_as_the_device_read_them(tmp_path: Path) -> None:
    """MP-6, TV-3: a 19200-baud host's `63 0D` reaches the device as the single byte `91`."""
    log = logged(tmp_path, "mp285", AT_19200)
    log.port.send(b"c\r")
    log.clock.advance(0.1)
    assert log.port.take() == b""
    (garbled,) = log.records(dir="rx")
    assert garbled["kind"] == "garbled" and garbled["hex"] == "91"
    assert "read 91 from the host's 63 sent at 19200 8N1" in garbled["summary"]


def test_mp285_parity_host_garbles_in_both_directions(tmp_path: Path) -> None:
    """MP-6, TV-4: an 8E1 host's `63 0D` is `63` with a framing error and a clean `0D` (only the
    corrupted character is `garbled`), a bad frame owing '1'; the host reads `31 0D` as `00 C3`."""
    log = logged(tmp_path, "mp285", LineSettings(9600, 8, "even", 1, False, False))
    log.port.send(b"c\r")
    log.clock.advance(0.1)
    assert log.port.take() == b"\x00\xc3"
    assert [(r["dir"], r["kind"], r["hex"]) for r in log.records()] == [
        ("rx", "garbled", "63"),
        ("rx", "stray", "63 0d"),
        ("tx", "garbled", "00"),
        ("tx", "garbled", "c3"),
    ]
    first_out = log.records(dir="tx")[0]["summary"]
    assert "read 31 with a framing error (delivered as 00) from the device's 31" in first_out
    assert first_out.endswith("reply to CR ending a bad frame (error '1' owed): error '1' frame error")


def test_mp285_status_sent_while_deaf_after_reset_is_lost(tmp_path: Path) -> None:
    """MP-55, MP-56: `r` is a frame with no reply; an `s` inside the deaf period is lost, not a
    command."""
    log = logged(tmp_path, "mp285")
    log.port.send(b"r\r")
    log.clock.advance(0.05)
    log.port.send(b"s\r")
    log.clock.advance(0.5)
    assert log.port.take() == b""
    frame, *lost = log.records(dir="rx")
    assert (frame["kind"], frame["summary"], frame["hex"]) == ("frame", "r", "72 0d")
    assert {(r["kind"], r["summary"]) for r in lost} == {("lost", "deaf after reset (MP-56)")}
    assert bytes.fromhex(" ".join(r["hex"] for r in lost)) == b"s\r"
    assert not log.records(dir="tx")


def test_mp285_bad_frame_is_stray_and_its_error_answers_it(tmp_path: Path) -> None:
    """MP-21: an unknown command byte is discarded through the CR, which owes error '4'."""
    log = logged(tmp_path, "mp285", timing=FAST)
    log.port.send(b"zz\r")
    assert log.port.take() == b"4\r"
    (stray,) = log.records(dir="rx")
    assert (stray["kind"], stray["hex"]) == ("stray", "7a 7a 0d")
    (reply,) = log.records(dir="tx")
    assert reply["summary"] == "reply to CR ending a bad frame (error '4' owed): error '4' bad command"


# ---- MS2000 --------------------------------------------------------------------------------------


def test_ms2000_line_in_three_chunks_is_one_frame_and_the_reply_names_it(tmp_path: Path) -> None:
    """MS-13: one line, one reply, however the host's writes split it."""
    log = logged(tmp_path, "ms2000", timing=FAST)
    for chunk in (b"W ", b"X", b"\r"):
        log.port.send(chunk)
        log.clock.advance(0.01)
    assert log.port.take() == b":A 0\r\n"
    records = log.records()
    assert kinds(records) == [("rx", "frame"), ("tx", "reply")]
    assert records[0]["hex"] == "57 20 58 0d" and records[0]["summary"] == "W X [WHERE]"
    assert records[1]["summary"] == ":A 0\\r\\n (reply to W X [WHERE])"


def test_ms2000_version_at_a_mismatched_baud_is_garbled(tmp_path: Path) -> None:
    """MS-4: every byte is read as b XOR 0x55, never as CR: `V\\r` is no command, gets no reply."""
    log = logged(tmp_path, "ms2000", AT_19200)
    log.port.send(b"V\r")
    log.clock.advance(0.1)
    assert log.port.take() == b""
    garbled = log.records(dir="rx")
    assert {r["kind"] for r in garbled} == {"garbled"}
    assert bytes.fromhex(" ".join(r["hex"] for r in garbled)) == bytes((0x56 ^ 0x55, 0x0D ^ 0x55))
    assert "device reads 56 as 03" in garbled[0]["summary"]


def test_ms2000_junk_before_a_command_is_stray(tmp_path: Path) -> None:
    """MS-4, TV-120: what a mismatched host left in the line buffer is dropped when its settings
    match again; the next line is read cleanly."""
    log = logged(tmp_path, "ms2000", AT_19200, timing=FAST)
    log.port.send(b"V\r")
    assert log.port.sink is not None
    log.port.sink.host_line(AT_9600)
    log.port.send(b"V\r")
    assert log.port.take() == b":A Version: USB-9.2k \r\n"
    records = log.records()
    assert kinds(records) == [("rx", "garbled"), ("rx", "stray"), ("rx", "frame"), ("tx", "reply")]
    assert records[1]["hex"] == "03 58" and "junk from a mismatched host" in records[1]["summary"]
    assert records[2]["summary"] == "V [VERSION]"


def test_ms2000_input_after_sp_is_lost(tmp_path: Path) -> None:
    """MS-113: after a bare `SP` the controller ignores all input."""
    log = logged(tmp_path, "ms2000", timing=FAST)
    log.port.send(b"SP\r")
    log.port.send(b"V\r")
    assert log.port.take() == b":A\r\n"
    assert kinds(log.records()) == [("rx", "frame"), ("tx", "reply"), ("rx", "lost")]
    assert log.records(kind="lost")[0]["summary"] == "silent after SP (MS-113)"


def test_ms2000_unsolicited_report_is_logged_as_such(tmp_path: Path) -> None:
    """MS-96: with `VB X=1` a completed move sends `N` on its own."""
    log = logged(tmp_path, "ms2000", timing=FAST)
    log.port.send(b"VB X=1\rM X=100\r")
    log.clock.advance(2.0)
    assert log.port.take() == b":A\r\n:A\r\nN\r\n"
    (report,) = log.records(kind="unsolicited")
    assert report["summary"] == "N\\r\\n (unsolicited)"


# ---- the probe device and the runner's own drops --------------------------------------------------


def test_probe_line_in_chunks_is_one_frame_and_the_delayed_reply_names_it(tmp_path: Path) -> None:
    log = logged(tmp_path, PROBE)
    log.trickle(b"D 100 late\r", 0.002)
    log.clock.advance(0.2)
    assert log.port.take() == b"late\r"
    records = log.records()
    assert kinds(records) == [("rx", "frame"), ("tx", "reply")]
    assert records[0]["summary"] == "line 'D 100 late'" and records[1]["summary"] == "reply to 'D 100 late'"


def test_runner_logs_what_it_drops(tmp_path: Path) -> None:
    """Faults and a hang-up lose bytes the device never heard or the host never got."""
    log = logged(tmp_path, PROBE, timing=FAST)
    runner = log.runner
    runner.inject("main", "drop", {"count": 1})
    log.port.send(b"E one\r")
    runner.inject("main", "hang", {})
    log.port.send(b"E two\r")
    runner.inject("main", "clear", {})
    log.port.send(b"E three\r")
    assert log.port.take() == b"three\r"
    lost = log.records(kind="lost")
    assert [(r["dir"], r["summary"]) for r in lost] == [
        ("tx", "not sent: drop fault: reply to 'E one'"),
        ("rx", "hang fault: the device hears nothing"),
    ]
    assert bytes.fromhex(lost[1]["hex"]) == b"E two\r"


def test_hang_up_discards_what_is_still_on_the_wire(tmp_path: Path) -> None:
    log = logged(tmp_path, PROBE)
    log.port.send(b"E hi\r")
    log.clock.advance(2 * CHAR)
    runner = log.runner
    runner.host_detached(runner.channels["main"])
    (lost,) = log.records(kind="lost")
    assert (lost["dir"], bytes.fromhex(lost["hex"])) == ("rx", b"hi\r")
    assert lost["summary"] == "still on the wire when the host hung up"


def test_records_are_in_device_time_order(tmp_path: Path) -> None:
    """A clock step that completes a reply and later host bytes still logs them in order."""
    log = logged(tmp_path, PROBE)
    log.port.send(b"B 20\r")
    log.clock.advance(6 * CHAR)
    log.port.send(b"E x\r")
    log.clock.advance(1.0)
    times = [r["t"] for r in log.records()]
    assert times == sorted(times) and len(times) == 4


def test_without_a_traffic_log_nothing_is_explained() -> None:
    """The hot path formats no summary when no log is kept."""
    clock = ManualClock()
    profile = load_profile("mp285")
    runner = DeviceRunner(
        lambda now: family("mp285").factory("dut", profile, now, DeviceServices()),  # type: ignore[union-attr]
        clock,
    )
    device = runner.device
    assert not device.explain
    device.receive(b"c\rzz\r", 0.0)
    assert device.take_rx_notes() == []
    assert [e.summary for e in device.take_output()] == [None, None]


# ---- what the log appends to ---------------------------------------------------------------------


def test_a_file_that_is_no_traffic_log_is_refused_untouched(tmp_path: Path) -> None:
    """`--log-traffic notes.txt` appended records to the user's notes."""
    notes = tmp_path / "notes.txt"
    notes.write_text("meeting at 10\n")
    before = notes.stat()
    with pytest.raises(NotATrafficLog, match="not a traffic log"):
        TrafficLog(notes)
    assert notes.read_text() == "meeting at 10\n"
    assert (notes.stat().st_size, notes.stat().st_mtime_ns) == (before.st_size, before.st_mtime_ns)


def test_an_empty_file_or_an_earlier_traffic_log_is_appended_to(tmp_path: Path) -> None:
    path = tmp_path / "traffic.jsonl"
    path.touch()
    first = TrafficLog(path)
    # a first line longer than what is read of it: its head tells it is a record
    first.record(0.5, "stage", "main", "tx", bytes(SNIFF_BYTES), "a long reply")
    first.event(0.6, "stage", {"ev": "move_complete"})
    first.close()
    second = TrafficLog(path)
    second.record(1.0, "stage", "main", "rx", b"c\r", None)
    second.close()
    records = [json.loads(line) for line in path.read_text().splitlines()]
    assert [(r["t"], r["dir"]) for r in records] == [(0.5, "tx"), (0.6, "ev"), (1.0, "rx")]


def test_a_log_starting_with_an_event_is_a_traffic_log(tmp_path: Path) -> None:
    path = tmp_path / "traffic.jsonl"
    first = TrafficLog(path)
    first.event(1e-06, "stage", {"ev": "ttl_out0", "level": 1})
    first.close()
    TrafficLog(path).close()


def test_a_device_is_written_to_unread() -> None:
    traffic = TrafficLog(Path("/dev/null"))
    traffic.record(0.0, "stage", "main", "rx", b"x", None)
    assert traffic.active
    traffic.close()


def test_reopen_onto_a_file_that_is_no_traffic_log_stops_logging_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SIGUSR1 after the path was replaced by another file: one error, logging off, file untouched."""
    path = tmp_path / "traffic.jsonl"
    traffic = TrafficLog(path)
    traffic.record(0.0, "stage", "main", "rx", b"x", None)
    path.rename(tmp_path / "traffic.1.jsonl")
    path.write_text("not mine to write\n")
    with caplog.at_level(logging.ERROR, "stage_emu.traffic"):
        traffic.reopen()
        for _ in range(10):
            traffic.record(1.0, "stage", "main", "rx", b"y", None)
    assert not traffic.active
    errors = [r.getMessage() for r in caplog.records]
    assert len(errors) == 1 and "cannot reopen: not a traffic log" in errors[0], errors
    assert path.read_text() == "not mine to write\n"
    path.unlink()
    traffic.reopen()  # the next SIGUSR1 starts afresh once the path is free
    assert traffic.active
    traffic.close()
