"""Control server edge cases: numbers that would wedge the clock, slow subscribers, connection cap,
stopping with clients connected, and the daemon's rate-limited loop error handler."""

from __future__ import annotations

import asyncio
import json
import logging
from pathlib import Path
from typing import Any

import pytest

from emulator.hosting import control
from emulator.hosting.clock import ScaledClock
from emulator.hosting.control import MAX_CLIENTS, SUBSCRIBER_BACKLOG, ControlServer
from emulator.hosting.daemon import ERROR_LOG_INTERVAL, _RateLimitedErrors
from emulator.hosting.trafficlog import TrafficLog


def reply(server: ControlServer, request: str) -> dict[str, Any]:
    return json.loads(server.handle_line(request.encode()))


@pytest.mark.parametrize(
    "request_line",
    [
        '{"op": "clock", "scale": NaN}',
        '{"op": "clock", "scale": Infinity}',
        '{"op": "step", "seconds": -Infinity}',
    ],
)
def test_non_finite_json_constants_are_refused(request_line: str) -> None:
    server = ControlServer(Path("unused"), {}, ScaledClock())
    answer = reply(server, request_line)
    assert answer["ok"] is False and "not a number JSON allows" in answer["error"]


@pytest.mark.parametrize(
    ("request_line", "message"),
    [
        ('{"op": "clock", "scale": 1e300}', "time scale must be between"),
        ('{"op": "clock", "scale": 0}', "time scale must be between"),
        ('{"op": "clock", "scale": "fast"}', "time scale must be a finite number"),
        ('{"op": "step", "seconds": 1e300}', "step must be between"),
        ('{"op": "step"}', "step needs 'seconds'"),
    ],
)
def test_clock_numbers_are_range_checked(request_line: str, message: str) -> None:
    clock = ScaledClock()
    server = ControlServer(Path("unused"), {}, clock)
    answer = reply(server, request_line)
    assert answer["ok"] is False and message in answer["error"]
    assert clock.scale == 1.0


class FakeTransport:
    def __init__(self) -> None:
        self.buffered = 0

    def get_write_buffer_size(self) -> int:
        return self.buffered


class FakeWriter:
    """A subscriber connection whose peer reads only when the test says so."""

    def __init__(self) -> None:
        self.transport = FakeTransport()
        self.lines: list[dict[str, Any]] = []

    def is_closing(self) -> bool:
        return False

    def write(self, data: bytes) -> None:
        self.transport.buffered += len(data)
        self.lines.append(json.loads(data))

    def read_all(self) -> list[dict[str, Any]]:
        self.transport.buffered = 0
        lines, self.lines = self.lines, []
        return lines


def test_a_subscriber_that_never_reads_is_bounded_and_told_what_it_missed(caplog) -> None:
    server = ControlServer(Path("unused"), {}, ScaledClock())
    writer = FakeWriter()
    server._subscribers["stage"] = {writer}  # type: ignore[dict-item]
    with caplog.at_level(logging.WARNING, "stage_emu.control"):
        for i in range(20000):
            server.publish("stage", {"ev": "tick", "i": i})
    assert writer.transport.buffered <= SUBSCRIBER_BACKLOG + 200
    kept = writer.read_all()
    server.publish("stage", {"ev": "tick", "i": "last"})
    after = writer.read_all()
    assert after[0] == {"ev": "dropped", "device": "stage", "count": 20000 - len(kept)}
    assert after[1]["i"] == "last"
    assert [r.message for r in caplog.records].count(
        "control: a subscriber to stage is not reading; dropping its events"
    ) == 1


def test_connections_beyond_the_cap_are_refused_with_a_sentence(tmp_path: Path) -> None:
    path = tmp_path / "c.sock"

    async def scenario() -> None:
        server = ControlServer(path, {}, ScaledClock())
        await server.start()
        held = [await asyncio.open_unix_connection(str(path)) for _ in range(MAX_CLIENTS)]
        for reader, writer in held[:1]:
            writer.write(b'{"op": "list"}\n')
            assert json.loads(await reader.readline())["ok"] is True
        reader, writer = await asyncio.open_unix_connection(str(path))
        answer = json.loads(await reader.readline())
        assert answer["ok"] is False and "too many control connections" in answer["error"]
        assert await reader.read() == b""
        for _, w in held:
            w.close()
        await server.stop()

    asyncio.run(scenario())


async def until(condition: Any, what: str) -> None:
    """Yield to the loop until `condition()` holds (a generous bound: this is no timing test)."""
    for _ in range(2000):
        if condition():
            return
        await asyncio.sleep(0.005)
    raise AssertionError(f"never happened: {what}")


def test_stop_ends_every_connection_so_none_is_left_to_be_cancelled(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A connection still served when the loop ends is cancelled with it, and asyncio (3.11) prints
    a CancelledError traceback for each: the daemon's SIGTERM with `ctl watch` attached. `stop` ends
    them all first: one idle, one mid-request, one whose peer stopped reading (cut off after
    STOP_GRACE_S)."""
    monkeypatch.setattr(control, "STOP_GRACE_S", 0.2)
    path = tmp_path / "c.sock"
    errors: list[dict[str, Any]] = []

    async def scenario() -> None:
        asyncio.get_running_loop().set_exception_handler(lambda loop, context: errors.append(context))
        server = ControlServer(path, {}, ScaledClock())
        await server.start()
        idle = await asyncio.open_unix_connection(str(path))
        _, mid = await asyncio.open_unix_connection(str(path))
        mid.write(b'{"id": 1, "op": "li')
        _, deaf = await asyncio.open_unix_connection(str(path))
        deaf.write(b'{"op": "clock"}\n' * 20000)  # ~2 MB of replies it never reads
        await until(lambda: len(server._clients) == 3, "three connections")
        await until(
            lambda: any(w.transport.get_write_buffer_size() > 0 for w in server._clients),
            "the server's replies to the deaf client pile up",
        )
        await server.stop()
        others = [task for task in asyncio.all_tasks() if task is not asyncio.current_task()]
        assert others == [], "connection tasks left for asyncio.run to cancel"
        assert await idle[0].read() == b"", "an idle client is told the channel closed"
        for writer in (idle[1], mid, deaf):
            writer.close()

    asyncio.run(scenario())
    assert errors == []


def test_loop_errors_are_logged_once_per_interval_with_a_count(caplog) -> None:
    now = [0.0]
    handler = _RateLimitedErrors(clock=lambda: now[0])
    error = OSError(24, "Too many open files")
    with caplog.at_level(logging.ERROR, "stage_emu.daemon"):
        for _ in range(1000):
            handler.handle(None, {"message": "socket.accept() out of system resource", "exception": error})  # type: ignore[arg-type]
        now[0] += ERROR_LOG_INTERVAL
        handler.handle(None, {"message": "socket.accept() out of system resource", "exception": error})  # type: ignore[arg-type]
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2
    assert "Too many open files" in messages[0] and "999 more like it" in messages[1]
    assert all(r.exc_info is None for r in caplog.records)  # no traceback for resource errors


def test_a_retry_on_a_server_closed_at_shutdown_is_no_traceback(caplog) -> None:
    """asyncio retries `accept` after EMFILE on a timer; when the daemon stops the control server in
    the meantime, the retry runs on a closed socket (ValueError: Invalid file descriptor: -1). Seen
    under load in the descriptor-exhaustion test: a traceback in the daemon's log at SIGTERM."""
    handler = _RateLimitedErrors()
    handler.closing = True
    context = {"message": "Exception in callback _start_serving", "exception": ValueError("fd -1")}
    with caplog.at_level(logging.INFO, "stage_emu.daemon"):
        handler.handle(None, context)  # type: ignore[arg-type]
    assert [r.getMessage() for r in caplog.records] == [
        "while shutting down: Exception in callback _start_serving: fd -1"
    ]
    assert caplog.records[0].levelno == logging.INFO and caplog.records[0].exc_info is None


def test_traffic_log_write_failure_is_logged_once_and_logging_stops(caplog) -> None:
    traffic = TrafficLog(Path("/dev/full"))
    with caplog.at_level(logging.ERROR, "stage_emu.traffic"):
        for _ in range(100):
            traffic.record(0.0, "stage", "main", "rx", b"W X\r", None)
    assert not traffic.active
    assert len(caplog.records) == 1 and "traffic logging stopped" in caplog.records[0].getMessage()
    traffic.reopen()
    assert traffic.active
    traffic.close()
