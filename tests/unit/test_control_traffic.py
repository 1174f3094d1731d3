"""Traffic subscriptions on the control channel: `{"op": "subscribe", "traffic": true}` makes the
device explain and pushes its traffic records; the model formats nothing again once the last
subscriber leaves (unsubscribes or disconnects) unless a traffic log is kept; `list` names the log."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices
from emulator.hosting.clock import ManualClock, ScaledClock
from emulator.hosting.control import SUBSCRIBER_BACKLOG, ControlServer
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import TrafficLog
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST, REALISTIC, char_time
from tests.support.memory_transport import MemoryTransport
from tests.unit.test_control import FakeWriter

SUBSCRIBE = '{"device": "stage", "op": "subscribe", "traffic": true}'
UNSUBSCRIBE = '{"device": "stage", "op": "unsubscribe", "traffic": true}'


def stage(timing: str = FAST, traffic: TrafficLog | None = None) -> tuple[DeviceRunner, MemoryTransport]:
    loaded = load_profile("ms2000")
    runner = DeviceRunner(
        lambda now: family("ms2000").factory("stage", loaded, now, DeviceServices()),  # type: ignore[union-attr]
        ManualClock(),
        traffic=traffic,
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(None)
    return runner, port


def ask(server: ControlServer, line: str, writer: Any) -> Any:
    answer = json.loads(server.handle_line(line.encode(), writer))
    assert answer["ok"], answer
    return answer["result"]


def test_a_traffic_subscriber_turns_explaining_on_and_gets_the_records() -> None:
    runner, port = stage()
    server = ControlServer(Path("unused"), {"stage": runner}, ScaledClock())
    writer, events_only = FakeWriter(), FakeWriter()
    assert runner.device.explain is False
    ask(server, '{"device": "stage", "op": "subscribe"}', events_only)
    assert runner.device.explain is False, "an events subscriber costs the model nothing"
    ask(server, SUBSCRIBE, writer)
    assert runner.device.explain is True
    port.send(b"W X Y\r")
    records = writer.read_all()
    assert [(r["ev"], r["device"], r["port"], r["dir"], r["kind"]) for r in records] == [
        ("traffic", "stage", "main", "rx", "frame"),
        ("traffic", "stage", "main", "tx", "reply"),
    ]
    assert records[0]["hex"] == "57 20 58 20 59 0d" and records[0]["summary"] == "W X Y [WHERE]"
    assert "reply to W X Y [WHERE]" in records[1]["summary"]
    assert {"t", "wall"} <= records[0].keys()
    assert events_only.read_all() == [], "traffic goes to traffic subscribers only"
    ask(server, UNSUBSCRIBE, writer)
    assert runner.device.explain is False
    port.send(b"W X\r")
    assert writer.read_all() == []


def test_with_a_traffic_log_explaining_stays_on_and_list_names_the_log(tmp_path: Path) -> None:
    log = TrafficLog(tmp_path / "traffic.jsonl")
    runner, port = stage(traffic=log)
    server = ControlServer(Path("unused"), {"stage": runner}, ScaledClock(), log.path)
    (entry,) = ask(server, '{"op": "list"}', None)
    assert entry["traffic_log"] == str(log.path)
    writer = FakeWriter()
    ask(server, SUBSCRIBE, writer)
    port.send(b"W X\r")
    pushed = [{k: v for k, v in r.items() if k != "ev"} for r in writer.read_all()]
    assert pushed == [json.loads(line) for line in log.path.read_text().splitlines()], "the same records"
    ask(server, UNSUBSCRIBE, writer)
    assert runner.device.explain is True
    port.send(b"W Y\r")
    assert len(log.path.read_text().splitlines()) == 4
    log.close()
    no_log = ControlServer(Path("unused"), {"stage": runner}, ScaledClock())
    assert ask(no_log, '{"op": "list"}', None)[0]["traffic_log"] is None


def test_a_reply_already_on_the_wire_when_watching_starts_is_not_recorded() -> None:
    """What left began before the subscription; the next reply, queued behind it, is recorded with
    its own last byte (not with the end of the bytes ahead of it)."""
    runner, port = stage(REALISTIC)
    server = ControlServer(Path("unused"), {"stage": runner}, ScaledClock())
    char = char_time(9600)
    clock = runner.clock.shared
    assert isinstance(clock, ManualClock)
    port.send(b"W X Y\rW Z\r")
    clock.advance(7 * char)  # `W X Y` is in and its reply on its way out; `W Z` still coming
    assert port.take() == b":"
    writer = FakeWriter()
    ask(server, SUBSCRIBE, writer)
    clock.advance(0.1)
    assert port.take() == b"A 0 0\r\n:A 0\r\n"
    rx, tx = writer.read_all()
    assert (rx["summary"], tx["summary"]) == ("W Z [WHERE]", ":A 0\\r\\n (reply to W Z [WHERE])")
    # `W Z` ends 4 characters after `W X Y`, whose 8-byte reply then still has 4 to go, then its own 6
    assert tx["t"] - rx["t"] == pytest.approx(10 * char, abs=1e-5)  # records keep 6 decimals


def test_a_subscriber_that_never_reads_is_bounded() -> None:
    runner, port = stage()
    server = ControlServer(Path("unused"), {"stage": runner}, ScaledClock())
    writer = FakeWriter()
    ask(server, SUBSCRIBE, writer)
    for _ in range(2000):
        port.send(b"W X Y\r")
        port.take()
    assert writer.transport.buffered <= SUBSCRIBER_BACKLOG + 400
    writer.read_all()
    port.send(b"W X\r")
    dropped, *after = writer.read_all()
    assert dropped["ev"] == "dropped" and dropped["count"] > 0
    assert [r["dir"] for r in after] == ["rx", "tx"]


def test_a_bad_traffic_flag_is_refused() -> None:
    runner, _ = stage()
    server = ControlServer(Path("unused"), {"stage": runner}, ScaledClock())
    request = b'{"device": "stage", "op": "subscribe", "traffic": 1}'
    answer = json.loads(server.handle_line(request, FakeWriter()))  # type: ignore[arg-type]
    assert answer["ok"] is False and "'traffic' must be true or false" in answer["error"]
    assert runner.device.explain is False


def test_a_subscriber_that_disconnects_turns_explaining_off(tmp_path: Path) -> None:
    runner, port = stage()
    path = tmp_path / "c.sock"
    calls: list[bool] = []
    off = asyncio.Event()
    watch = runner.watch_traffic

    def spy(sink: Any) -> None:
        watch(sink)
        calls.append(sink is not None)
        if sink is None:
            off.set()

    runner.watch_traffic = spy  # type: ignore[method-assign]

    async def scenario() -> None:
        server = ControlServer(path, {"stage": runner}, ScaledClock())
        await server.start()
        connections = [await asyncio.open_unix_connection(str(path)) for _ in range(2)]
        for reader, writer in connections:
            writer.write(SUBSCRIBE.encode() + b"\n")
            assert json.loads(await reader.readline())["ok"] is True
        assert runner.device.explain is True
        port.send(b"W X\r")
        for reader, _ in connections:
            assert json.loads(await reader.readline())["summary"] == "W X [WHERE]"
        for _, writer in connections:
            writer.close()
        await asyncio.wait_for(off.wait(), 10)
        assert calls == [True, False], "on with the first subscriber, off when the last one left"
        assert runner.device.explain is False
        await server.stop()

    asyncio.run(scenario())
