"""The daemon as a subprocess, with pyserial as the host (test-only probe device).

Most tests share one daemon (starting one costs about a second, more on a loaded machine); each gets
its devices factory-fresh, the clock at scale 1 and no fault. Timing is checked on the device's own
timestamps (its traffic records), never on when the host happened to be scheduled; the host's side
is held only to what a loaded machine cannot break: bytes never arrive sooner than the wire allows.
"""

from __future__ import annotations

import json
import os
import select
import socket
import stat
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import serial

from emulator.control_client import ControlClient, ControlFailure
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

PROBE = ROOT / "tests" / "support" / "probe.yaml"
CHAR_9600 = 10 / 9600
#: the runner releases a byte up to this much before its instant (emulator/hosting/walltimer.py's early
#: wake-up, 0.5 ms at most), so the host may see the last byte that much sooner than the wire's end
EARLY_S = 0.001
#: generous: only a hang takes this long on any machine
HANG_S = 10.0
#: a command's whole run, its start included: generous, a loaded machine has taken ten seconds to
#: start a Python process
RUN_S = 60.0


def rig(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(body)
    return path


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    workdir = tmp_path_factory.mktemp("probe")
    path = rig(
        workdir,
        f"spec: 1\ndevices:\n  - name: probe\n    profile: {PROBE}\n"
        f"  - name: fast\n    profile: {PROBE}\n    ports: [{{timing: fast, mode: 0640}}]\n",
    )
    daemon = start_daemon(workdir, [str(path)], expect_ports=2, test_devices=True)
    yield daemon
    assert daemon.stop() == 0, daemon.stderr()


@pytest.fixture
def probe_daemon(served: RunningDaemon) -> Iterator[RunningDaemon]:
    """The shared daemon as a fresh one would be: devices reset, clock at scale 1, no fault."""
    with ControlClient(served.control_path) as client:
        for device in ("probe", "fast"):
            client.fault(device, "clear")
            client.reset(device)
        client.resume()
        client.clock(scale=1.0)
    yield served
    assert served.proc.poll() is None, served.stderr()


@pytest.fixture
def client(probe_daemon: RunningDaemon) -> Iterator[ControlClient]:
    """A control connection of the test's own, closed after it (the shared daemon serves 64)."""
    with ControlClient(probe_daemon.control_path) as control:
        yield control


def ask(port: serial.Serial, command: bytes, size: int) -> bytes:
    port.write(command)
    return port.read(size)


def pushed(subscriber: ControlClient, count: int) -> list[dict[str, Any]]:
    """The next `count` messages pushed to a subscriber: device events, or traffic records (`rx`,
    `tx`, with the device instant `t`) for a traffic subscriber. Waits for them, not for silence."""
    messages: list[dict[str, Any]] = []
    for message in subscriber.events(timeout=HANG_S):
        messages.append(message)
        if len(messages) == count:
            break
    assert len(messages) == count, messages
    return messages


def test_ports_appear_with_the_right_modes(probe_daemon: RunningDaemon) -> None:
    by_device = {p["device"]: p for p in probe_daemon.ports}
    assert set(by_device) == {"probe", "fast"}
    for name, mode in (("probe", 0o600), ("fast", 0o640)):
        link = Path(by_device[name]["path"])
        assert link == probe_daemon.workdir / "links" / name
        assert link.is_symlink() and os.readlink(link) == by_device[name]["pts"]
        assert stat.S_IMODE(os.stat(by_device[name]["pts"]).st_mode) == mode
    assert stat.S_IMODE(os.stat(probe_daemon.control_path).st_mode) == 0o600
    with serial.Serial(by_device["probe"]["path"], 9600, timeout=HANG_S) as port:
        assert ask(port, b"E hello\r", 6) == b"hello\r"


def test_pacing_at_9600_delivers_100_bytes_in_104_ms(probe_daemon: RunningDaemon) -> None:
    with (
        ControlClient(probe_daemon.control_path) as watcher,
        serial.Serial(probe_daemon.port("probe"), 9600, timeout=HANG_S) as port,
    ):
        ask(port, b"E warm\r", 5)
        watcher.subscribe("probe", traffic=True)
        start = time.monotonic()
        port.write(b"B 100\r")
        data = port.read(100)
        elapsed = time.monotonic() - start
        request, reply = pushed(watcher, 2)
    assert data == b"x" * 100
    assert (request["dir"], reply["dir"]) == ("rx", "tx")
    # The device's own instants: the reply starts when the request is complete and its last byte
    # leaves 100 characters of 10 bits at 9600 baud later (104.2 ms; records keep 6 decimals).
    assert reply["t"] - request["t"] == pytest.approx(100 * CHAR_9600, abs=2e-6)
    # The host's side, which load can only lengthen: never sooner than the wire carries them.
    assert elapsed >= 100 * CHAR_9600 - EARLY_S


def test_fast_timing_is_immediate(probe_daemon: RunningDaemon) -> None:
    with (
        ControlClient(probe_daemon.control_path) as watcher,
        serial.Serial(probe_daemon.port("fast"), 9600, timeout=HANG_S) as port,
    ):
        ask(port, b"E warm\r", 5)
        watcher.subscribe("fast", traffic=True)
        data = ask(port, b"B 100\r", 100)
        request, reply = pushed(watcher, 2)
    assert data == b"x" * 100
    # Unpaced: the whole reply leaves at the device instant the request was complete, where the
    # wire would take 104 ms (the express path without a watcher is fuzzed against this one in
    # tests/unit/test_runner_express.py).
    assert (request["dir"], reply["dir"]) == ("rx", "tx")
    assert reply["t"] == request["t"]


def test_host_settings_are_seen_by_the_device(probe_daemon: RunningDaemon, client: ControlClient) -> None:
    with serial.Serial(probe_daemon.port("probe"), 19200, stopbits=2, rtscts=True, timeout=HANG_S) as port:
        assert ask(port, b"E x\r", 2) == b"x\r"
        assert (
            client.get("probe", "host") == "19200 ??2 rtscts (data bits, parity not visible)"
        )  # parity and data bits are invisible on a PTY
        port.baudrate = 4800
        assert ask(port, b"E y\r", 2) == b"y\r"
        assert client.get("probe", "host") == "4800 ??2 rtscts (data bits, parity not visible)"
    listing = {d["device"]: d for d in client.list()}
    assert listing["probe"]["family"] == "probe"


def fd_count(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def test_200_attach_detach_cycles_leak_nothing(probe_daemon: RunningDaemon, client: ControlClient) -> None:
    path = probe_daemon.port("fast")

    def settled_fd_count() -> int:
        # the daemon handles a hang-up asynchronously and briefly holds a peer fd to flush stale output
        until(lambda: not attached(client, "fast"))
        return fd_count(probe_daemon.proc.pid)

    with serial.Serial(path, 9600, timeout=HANG_S) as port:
        assert ask(port, b"E first\r", 6) == b"first\r"
    before = settled_fd_count()
    for i in range(200):
        with serial.Serial(path, 9600, timeout=HANG_S) as port:
            assert ask(port, f"E {i}\r".encode(), len(str(i)) + 1) == f"{i}\r".encode()
    assert settled_fd_count() == before
    assert probe_daemon.proc.poll() is None


def test_unread_output_does_not_reach_the_next_opener(
    probe_daemon: RunningDaemon, client: ControlClient
) -> None:
    path = probe_daemon.port("fast")
    with serial.Serial(path, 9600, timeout=HANG_S) as port:
        port.write(b"E stale\r")
        port.flush()
        until(lambda: client.snapshot("fast", "lines") >= 1)  # then its reply is queued
    until(lambda: not attached(client, "fast"))  # the daemon handles the hang-up asynchronously
    # A naive opener (no flush on open, unlike pyserial) must not see the departed host's reply.
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, b"E fresh\r")
        assert select.select([fd], [], [], HANG_S)[0], "no reply"
        assert os.read(fd, 100) == b"fresh\r"
    finally:
        os.close(fd)


def until(condition: Callable[[], bool]) -> None:
    """Until `condition()` holds; each check is a control request, which the daemon's answer paces."""
    deadline = time.monotonic() + HANG_S
    while not condition():
        assert time.monotonic() < deadline, "not in time"


def attached(client: ControlClient, device: str) -> bool:
    listing = {d["device"]: d for d in client.list()}
    return listing[device]["ports"][0]["attached"]


def test_idle_daemon_does_not_spin(probe_daemon: RunningDaemon) -> None:
    with serial.Serial(probe_daemon.port("probe"), 9600, timeout=HANG_S) as port:
        ask(port, b"E x\r", 2)
    ticks = os.sysconf("SC_CLK_TCK")

    def cpu() -> float:
        fields = Path(f"/proc/{probe_daemon.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / ticks

    before = cpu()
    ControlClient(probe_daemon.control_path).close()
    time.sleep(1.0)  # measuring idleness needs elapsed time; nothing to wait for
    # Idle is a few milliseconds of CPU; a spinning loop takes its share of a core for the whole
    # second, well over this even beside other busy processes (load only lowers the figure).
    assert cpu() - before < 0.1


def test_link_occupied_by_a_regular_file_is_refused(tmp_path: Path) -> None:
    occupied = tmp_path / "ttyStage"
    occupied.write_text("precious")
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "tests.support.serve",
            "serve",
            "--profile",
            f"{PROBE}:{occupied}",
            "--control",
            str(tmp_path / "c.sock"),
            "--link-dir",
            str(tmp_path),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=RUN_S,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert result.returncode == 1
    assert result.stderr.strip() == (
        f"stage-emu: {occupied} already exists and is a file, not a stale pty link; "
        "remove it or choose another link path"
    )
    assert occupied.read_text() == "precious"


def test_stale_link_is_replaced(tmp_path: Path) -> None:
    link = tmp_path / "ttyStale"
    link.symlink_to("/dev/pts/999999")
    daemon = start_daemon(tmp_path, ["--profile", f"{PROBE}:{link}"], expect_ports=1, test_devices=True)
    assert os.readlink(link) == daemon.ports[0]["pts"]
    daemon.stop()


def test_control_round_trips(probe_daemon: RunningDaemon, client: ControlClient) -> None:
    with ControlClient(probe_daemon.control_path) as events:
        assert events.subscribe("fast") is True
        with serial.Serial(probe_daemon.port("fast"), 9600, timeout=HANG_S) as port:
            assert ask(port, b"E one\r", 4) == b"one\r"
            assert client.input("fast", "say", text="hi") is True
            assert port.read(2) == b"hi"
            assert client.snapshot("fast", "lines") == 1
            assert client.fault("fast", "drop", count=1)["drop_replies"] == 1
            port.write(b"E dropped\r")
            assert ask(port, b"E kept\r", 5) == b"kept\r"
        assert [e["text"] for e in pushed(events, 3)] == ["E one", "E dropped", "E kept"]
    state = client.clock(scale=2.0)
    assert state["scale"] == 2.0
    assert client.pause()["paused"] is True
    now = client.clock()["now"]
    assert client.step(1.5)["now"] == pytest.approx(now + 1.5)
    assert client.resume()["paused"] is False
    assert client.reset("fast") is True
    assert client.snapshot("fast", "lines") == 0


@pytest.mark.parametrize(
    ("request_line", "error"),
    [
        (b"this is not json\n", "not a JSON object"),
        (b"[1, 2]\n", "a request must be a JSON object"),
        (b'{"op": "explode"}\n', "unknown op 'explode'"),
        (b'{"device": "nosuch", "get": "x"}\n', "no device 'nosuch'; devices: probe, fast"),
        (b'{"device": "probe", "in": "nosuch"}\n', "probe: no input 'nosuch'; known: say"),
        (b'{"device": "probe", "in": 5}\n', "'in' must be a non-empty string"),
        (b'{"device": "probe", "op": "fault", "fault": "melt"}\n', "unknown fault 'melt'"),
        (b'{"op": "clock", "scale": -1}\n', "time scale must be between"),
        (b'{"device": "probe", "op": "snapshot", "path": "no.such"}\n', "no 'no' in snapshot path"),
    ],
)
def test_malformed_control_requests_get_errors(
    probe_daemon: RunningDaemon, request_line: bytes, error: str
) -> None:
    with socket.socket(socket.AF_UNIX) as sock:
        sock.settimeout(5)
        sock.connect(str(probe_daemon.control_path))
        sock.sendall(request_line)
        reply = json.loads(sock.makefile().readline())
    assert reply["ok"] is False and error in reply["error"]
    with ControlClient(probe_daemon.control_path) as client:
        with pytest.raises(ControlFailure):
            client.request({"op": "nope"})
        assert client.list()


def test_time_scale_ready_file_and_traffic_log(tmp_path: Path) -> None:
    ready = tmp_path / "ready.json"
    traffic = tmp_path / "traffic.jsonl"
    daemon = start_daemon(
        tmp_path,
        [
            "--profile",
            str(PROBE),
            "--time-scale",
            "20",
            "--timing",
            "fast",
            "--ready-file",
            str(ready),
            "--log-traffic",
            str(traffic),
        ],
        expect_ports=1,
        test_devices=True,
    )
    try:
        info = json.loads(ready.read_text())
        assert info["ports"] == daemon.ports and info["control"] == str(daemon.control_path)
        with (
            ControlClient(daemon.control_path) as client,
            serial.Serial(daemon.port("probe"), 9600, timeout=HANG_S) as port,
        ):
            before, device_before, after_before = device_now(client)
            assert ask(port, b"D 2000 done\r", 5) == b"done\r"
            before_after, device_after, after = device_now(client)
        # Device time ran 20 times as fast as the host's clock over the exchange, so the reply's
        # 2 device seconds (below) took 0.1 s: bounded on both sides by host instants taken around
        # the daemon's readings, which a loaded machine cannot make fail.
        assert 20 * (before_after - after_before) <= device_after - device_before <= 20 * (after - before)
    finally:
        assert daemon.stop() == 0
    assert not ready.exists()
    records = [json.loads(line) for line in traffic.read_text().splitlines()]
    entries = [e for e in records if e["dir"] != "ev"]  # the probe's `line` events are logged too
    assert [(e["dir"], bytes.fromhex(e["hex"])) for e in entries] == [
        ("rx", b"D 2000 done\r"),
        ("tx", b"done\r"),
    ]
    assert entries[1]["t"] - entries[0]["t"] == pytest.approx(2.0, abs=2e-6)  # records keep 6 decimals


def device_now(client: ControlClient) -> tuple[float, float, float]:
    """The daemon's device time, with host instants taken just before and after asking for it."""
    before = time.monotonic()
    now = client.clock()["now"]
    return before, now, time.monotonic()
