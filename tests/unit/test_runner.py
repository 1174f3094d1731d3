"""The device host on a manual clock: contract calls, pacing, timers, faults, traffic log, and the
bounds between host and device (input backlog, output drops, fault parameters)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock, ScaledClock
from emulator.hosting.port import INPUT_BACKLOG, OUTPUT_BACKLOG
from emulator.hosting.runner import RELEASE_EARLY_S, DeviceRunner
from emulator.hosting.trafficlog import TrafficLog
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST, REALISTIC
from tests.support.memory_transport import MemoryTransport
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)

CHAR = 10 / 9600
HOST_9600 = LineSettings(9600, None, None, 1, False, False)


@dataclass
class Host:
    clock: ManualClock
    runner: DeviceRunner
    port: MemoryTransport
    events: list[tuple[str, dict]]


def make(
    timing: str = REALISTIC,
    overrides: dict | None = None,
    traffic: TrafficLog | None = None,
    port: MemoryTransport | None = None,
    attach: LineSettings = HOST_9600,
) -> Host:
    clock = ManualClock()
    profile = load_profile(PROBE, overrides=overrides)
    events: list[tuple[str, dict]] = []
    runner = DeviceRunner(
        lambda now: family("probe").factory("probe-0", profile, now, DeviceServices()),
        clock,
        traffic=traffic,
        on_event=lambda name, ev: events.append((name, ev)),
    )
    port = port or MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(attach)
    return Host(clock, runner, port, events)


def test_fast_timing_is_immediate() -> None:
    h = make(FAST)
    runner = h.runner
    port = h.port
    events = h.events
    port.send(b"E hi\r")
    assert port.take() == b"hi\r"
    assert runner.device.received == [(0.0, b"E hi\r")]
    assert events == [("probe-0", {"ev": "line", "text": "E hi"})]


def test_realistic_input_reaches_device_at_end_of_wire_time() -> None:
    h = make()
    clock = h.clock
    runner = h.runner
    port = h.port
    port.send(b"E hi\r")
    assert runner.device.received == []
    clock.advance(5 * CHAR)
    times = [t for t, _ in runner.device.received]
    assert times == pytest.approx([CHAR * (i + 1) for i in range(5)])


def test_realistic_output_is_paced_per_character() -> None:
    h = make()
    clock = h.clock
    port = h.port
    port.send(b"B 100\r")
    clock.advance(6 * CHAR)  # command fully received
    assert port.take() == b""
    clock.advance(50 * CHAR + 1e-9)
    assert port.take() == b"x" * 50
    clock.advance(50 * CHAR)
    assert port.take() == b"x" * 50
    # 100 bytes at 9600 8N1: 104.17 ms from the first start bit to the last stop bit


def test_timers_fire_at_their_deadline() -> None:
    h = make(FAST)
    clock = h.clock
    port = h.port
    port.send(b"D 250 late\r")
    clock.advance(0.2499)
    assert port.take() == b""
    clock.advance(0.0001)
    assert port.take() == b"late\r"


def test_pace_line_false_is_fast_even_on_realistic_port() -> None:
    h = make(REALISTIC, {"knobs": {"pace_line": False}})
    port = h.port
    port.send(b"E x\r")
    assert port.take() == b"x\r"


class WireTransport(MemoryTransport):
    """A port whose UARTs pace the line themselves, as a serial port's do."""

    wire_paces = True


def test_a_line_its_uarts_pace_is_not_paced_again() -> None:
    # A serial port: the driver delivers the host's bytes once received, and sends the device's
    # bytes at the baud rate from the instant it gets them. Pacing either direction here as well
    # would put every byte one character time (or more) late.
    h = make(REALISTIC, port=WireTransport())
    h.port.send(b"E hi\r")
    assert [t for t, _ in h.runner.device.received] == [0.0]
    assert h.port.take() == b"hi\r"
    h.port.send(b"B 100\r")
    assert h.port.take() == b"x" * 100


def test_no_output_while_detached_and_host_settings_reach_device() -> None:
    h = make(FAST)
    runner = h.runner
    port = h.port
    assert runner.device.host == LineSettings(9600, None, None, 1, False, False)
    runner.host_detached(runner.channels["main"])
    assert runner.device.host is None
    runner.call(lambda now: runner.device.control_input("say", {"text": "lost"}, now))
    assert port.take() == b""


def test_mismatch_logged_once_per_change(caplog: pytest.LogCaptureFixture) -> None:
    h = make(FAST)
    port = h.port
    with caplog.at_level("WARNING"):
        port.sink.host_line(LineSettings(19200, None, None, 1, False, False))
        port.sink.host_line(LineSettings(19200, None, None, 1, False, False))
        port.send(b"E x\r")
        port.send(b"E y\r")
        port.sink.host_line(LineSettings(19200, None, None, 2, False, False))
        port.send(b"E z\r")
    lines = [r.getMessage() for r in caplog.records]
    assert lines == [
        "probe-0/main: host uses 19200 8N1, device expects 9600 8N1; the probe ignores it",
        "probe-0/main: host uses 19200 8N2, device expects 9600 8N1; the probe ignores it",
    ]


def mismatch_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "host uses" in r.getMessage()]


def test_a_host_that_fixes_its_settings_before_writing_gets_no_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """boost::asio opens a port at the pty's default speed, then sets its own before writing."""
    port = MemoryTransport()
    with caplog.at_level("WARNING"):
        h = make(REALISTIC, port=port, attach=LineSettings(38400, None, None, 1, False, False))
        port.sink.host_line(LineSettings(9600, None, None, 1, False, False))
        port.send(b"E hi\r")
        h.clock.advance(20 * CHAR)
    assert port.take() == b"hi\r"
    assert mismatch_warnings(caplog) == []


def test_writing_at_mismatched_settings_warns_once(caplog: pytest.LogCaptureFixture) -> None:
    port = MemoryTransport()
    with caplog.at_level("WARNING"):
        h = make(REALISTIC, port=port, attach=LineSettings(38400, None, None, 1, False, False))
        assert mismatch_warnings(caplog) == [], "no byte has crossed yet"
        port.send(b"E hi\r")
        h.clock.advance(20 * CHAR)
        port.send(b"E again\r")
        h.clock.advance(20 * CHAR)
    assert mismatch_warnings(caplog) == [
        "probe-0/main: host uses 38400 8N1, device expects 9600 8N1; the probe ignores it"
    ]


def test_device_output_to_a_mismatched_host_warns_once(caplog: pytest.LogCaptureFixture) -> None:
    port = MemoryTransport()
    with caplog.at_level("WARNING"):
        h = make(FAST, port=port, attach=LineSettings(38400, None, None, 1, False, False))
        runner = h.runner
        assert mismatch_warnings(caplog) == []
        runner.call(lambda now: runner.device.control_input("say", {"text": "one"}, now))
        runner.call(lambda now: runner.device.control_input("say", {"text": "two"}, now))
    assert port.take() == b"onetwo"
    assert mismatch_warnings(caplog) == [
        "probe-0/main: host uses 38400 8N1, device expects 9600 8N1; the probe ignores it"
    ]


def test_faults_drop_corrupt_latency_hang() -> None:
    h = make(FAST)
    clock = h.clock
    runner = h.runner
    port = h.port
    runner.inject("main", "drop", {"count": 1})
    port.send(b"E one\rE two\r")
    assert port.take() == b"two\r"
    runner.inject("main", "corrupt", {"count": 2})
    port.send(b"E ab\r")
    assert port.take() == bytes([ord("a") ^ 0xFF, ord("b") ^ 0xFF]) + b"\r"
    runner.inject("main", "latency", {"ms": 100})
    port.send(b"E late\r")
    assert port.take() == b""
    clock.advance(0.1)
    assert port.take() == b"late\r"
    runner.inject("main", "latency", {"ms": 0})
    runner.inject("main", "hang", {"seconds": 1})
    port.send(b"E ignored\r")
    assert port.take() == b""
    clock.advance(1.0)
    port.send(b"E back\r")
    assert port.take() == b"back\r"


def test_disconnect_fault_vanishes_and_returns() -> None:
    h = make(FAST)
    clock = h.clock
    runner = h.runner
    port = h.port
    runner.inject("main", "disconnect", {"seconds": 2})
    assert port.vanished and not runner.channels["main"].attached
    clock.advance(2.0)
    assert not port.vanished


@pytest.mark.parametrize(
    ("fault", "params", "message"),
    [
        ("explode", {}, "unknown fault 'explode'"),
        ("drop", {"count": 0}, "count must be a number >= 1"),
        ("latency", {"ms": "x"}, "ms must be a number >= 0"),
        ("hang", {"seconds": -1}, "seconds must be a number >= 0"),
    ],
)
def test_bad_faults_are_refused(fault: str, params: dict, message: str) -> None:
    h = make(FAST)
    runner = h.runner
    with pytest.raises(ValueError, match=message):
        runner.inject("main", fault, params)


def test_reset_gives_a_fresh_model() -> None:
    h = make(FAST)
    runner = h.runner
    port = h.port
    port.send(b"E a\r")
    assert runner.device.lines == 1
    old = runner.device
    forgotten: list[object] = []
    old.forget_nonvolatile = lambda: forgotten.append(old)
    runner.reset()
    assert forgotten == [old], "a factory reset erases the old model's saved settings first"
    assert runner.device.lines == 0
    assert runner.device.host is not None


def test_traffic_log_records_both_directions(tmp_path: Path) -> None:
    path = tmp_path / "traffic.jsonl"
    traffic = TrafficLog(path)
    h = make(FAST, traffic=traffic)
    port = h.port
    port.send(b"E ok\r")
    traffic.close()
    entries = [json.loads(line) for line in path.read_text().splitlines()]
    assert [(e["dir"], e.get("hex"), e.get("kind")) for e in entries] == [
        ("rx", "45 20 6f 6b 0d", "frame"),
        ("tx", "6f 6b 0d", "reply"),
        ("ev", None, None),  # the model's pushed event, after the traffic of its instant
    ]
    assert entries[0]["device"] == "probe-0" and entries[0]["summary"] == "line 'E ok'"
    assert entries[1]["summary"] == "reply to 'E ok'"
    assert entries[2] == {**entries[2], "device": "probe-0", "ev": "line", "text": "E ok", "t": 0.0}


# ---- bounds between host and device --------------------------------------------------------------


def test_input_backlog_bounds_what_the_port_takes_and_reopens_at_half() -> None:
    h = make()
    port = h.port
    assert port.room() == INPUT_BACKLOG >= 1588  # an MP-285 99-vector download fits in one write
    port.send(b"x" * 1000)
    assert port.room() == INPUT_BACKLOG - 1000
    port.send(b"x" * (INPUT_BACKLOG - 1000))
    assert port.room() == 0
    resumes = port.resumes
    h.clock.advance((INPUT_BACKLOG // 2 - 1) * CHAR)  # one byte short of half delivered
    assert port.resumes == resumes, "no resume while the backlog is above half"
    h.clock.advance(CHAR)
    assert port.resumes > resumes
    assert port.room() == INPUT_BACKLOG // 2
    assert len(h.runner.device.received) == INPUT_BACKLOG // 2


def test_output_backlog_stops_input_until_it_drains() -> None:
    h = make()
    port = h.port
    port.send(b"B 5000\r")
    h.clock.advance(7 * CHAR)  # the command is in; 5000 bytes of reply wait for the wire
    assert port.room() == 0
    resumes = port.resumes
    h.clock.advance((5000 - OUTPUT_BACKLOG // 2) * CHAR)
    assert port.resumes > resumes
    assert port.room() == INPUT_BACKLOG
    assert port.take() == b"x" * (5000 - OUTPUT_BACKLOG // 2)


def test_a_hung_device_still_paces_what_the_port_takes() -> None:
    h = make()
    h.runner.inject("main", "hang", {})
    h.port.send(b"E lost\r")
    assert h.port.room() == INPUT_BACKLOG - 7
    h.clock.advance(7 * CHAR)
    assert h.port.room() == INPUT_BACKLOG
    assert h.runner.device.received == [] and h.port.take() == b""


def test_output_drops_are_counted_and_logged_once_per_episode(caplog: pytest.LogCaptureFixture) -> None:
    h = make(FAST, port=MemoryTransport(output_limit=8))
    port = h.port
    stats = h.runner.channels["main"].stats
    with caplog.at_level("INFO", logger="stage_emu.runner"):
        for _ in range(3):
            port.send(b"E abcdef\r")  # 7 bytes of reply each: the second and third do not fit
        assert port.take() == b"abcdef\r" + b"a"
        assert stats.describe() == {"output_dropped": 13, "input_discarded": 0}
        port.send(b"E ok\r")
        assert port.take() == b"ok\r"
        port.send(b"E 123456789\r")
    messages = [(r.levelname, r.getMessage()) for r in caplog.records if "output" in r.getMessage()]
    assert messages == [
        (
            "WARNING",
            "probe-0/main: host is not reading; output that does not fit its buffer is dropped "
            "(6 bytes dropped on this port so far)",
        ),
        ("INFO", "probe-0/main: host takes output again"),
        (
            "WARNING",
            "probe-0/main: host is not reading; output that does not fit its buffer is dropped "
            "(15 bytes dropped on this port so far)",
        ),
    ]


def test_input_discarded_at_hangup_is_counted() -> None:
    h = make()
    ch = h.runner.channels["main"]
    h.port.send(b"E never heard\r")
    h.clock.advance(4 * CHAR)
    assert h.port.sink is not None
    h.port.sink.input_discarded(100)  # what the transport threw away unread
    h.runner.host_detached(ch)
    assert ch.stats.describe() == {"output_dropped": 0, "input_discarded": 110}
    assert h.port.room() == INPUT_BACKLOG


@pytest.mark.parametrize(
    ("fault", "params", "message"),
    [
        ("latency", {}, "latency needs ms=M"),
        ("latency", {"ms": float("nan")}, "ms must be a number >= 0 and <= 60000, got nan"),
        ("latency", {"ms": 60001}, "ms must be a number >= 0 and <= 60000, got 60001"),
        ("hang", {"seconds": float("inf")}, "seconds must be a number >= 0 and <= 86400, got inf"),
        ("disconnect", {"seconds": 1e300}, "seconds must be a number >= 0 and <= 86400, got 1e[+]300"),
        ("drop", {"count": 10**7}, "count must be a number >= 1 and <= 1000000, got 10000000"),
        ("corrupt", {"count": 1.5}, "count must be a whole number, got 1.5"),
        ("hang", {"second": 5}, "hang takes only seconds; got second"),
        ("clear", {"count": 1}, "clear takes no parameters; got count"),
    ],
)
def test_fault_parameters_are_checked(fault: str, params: dict, message: str) -> None:
    h = make(FAST)
    with pytest.raises(ValueError, match=message):
        h.runner.inject("main", fault, params)
    assert h.runner.channels["main"].faults.describe() == make(FAST).runner.channels["main"].faults.describe()


def test_paced_output_is_released_half_a_millisecond_early_on_a_running_clock() -> None:
    """Without a timer of its own (pumped by its host, as the in-process URL does, or on the loop's
    millisecond timers) each paced byte is released up to RELEASE_EARLY_S before its instant
    (centred on it) rather than up to 1 ms after; a manual clock is exact."""
    wall = [100.0]
    clock = ScaledClock(1.0, wall=lambda: wall[0])
    profile = load_profile(PROBE)
    runner = DeviceRunner(
        lambda now: family("probe").factory("probe-0", profile, now, DeviceServices()), clock
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, REALISTIC)
    port.attach(LineSettings(9600, None, None, 1, False, False))
    port.send(b"E x\r")
    wall[0] += 4 * CHAR  # the request's wire time: the device has the line and replies
    runner.pump()
    first_byte_at = 4 * CHAR + CHAR
    wall[0] = 100.0 + first_byte_at - RELEASE_EARLY_S * 1.2
    runner.pump()
    assert port.take() == b""
    wall[0] = 100.0 + first_byte_at - RELEASE_EARLY_S * 0.8
    runner.pump()
    assert port.take() == b"x"


def test_close_lets_the_device_save_what_it_keeps_at_rest() -> None:
    """`close` (daemon shutdown) brings the device up to now and calls its `shut_down` hook before
    the ports go, so a save the model would make a little later is made now."""
    h = make(FAST)
    seen: list[float] = []
    h.runner.device.shut_down = seen.append  # type: ignore[method-assign]
    h.clock.advance(1.5)
    h.runner.close()
    assert seen == [1.5]
