"""The daemon as a subprocess, with pyserial as the host (test-only probe device)."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial

from emulator.control_client import ControlClient, ControlFailure
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

PROBE = ROOT / "tests" / "support" / "probe.yaml"
CHAR_9600 = 10 / 9600


def rig(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(body)
    return path


@pytest.fixture
def probe_daemon(tmp_path: Path):
    path = rig(
        tmp_path,
        f"spec: 1\ndevices:\n  - name: probe\n    profile: {PROBE}\n"
        f"  - name: fast\n    profile: {PROBE}\n    ports: [{{timing: fast, mode: 0640}}]\n",
    )
    daemon = start_daemon(tmp_path, [str(path)], expect_ports=2, test_devices=True)
    yield daemon
    daemon.stop()


def ask(port: serial.Serial, command: bytes, size: int) -> bytes:
    port.write(command)
    return port.read(size)


def test_ports_appear_with_the_right_modes(probe_daemon: RunningDaemon, tmp_path: Path) -> None:
    by_device = {p["device"]: p for p in probe_daemon.ports}
    assert set(by_device) == {"probe", "fast"}
    for name, mode in (("probe", 0o600), ("fast", 0o640)):
        link = Path(by_device[name]["path"])
        assert link == tmp_path / "links" / name
        assert link.is_symlink() and os.readlink(link) == by_device[name]["pts"]
        assert stat.S_IMODE(os.stat(by_device[name]["pts"]).st_mode) == mode
    assert stat.S_IMODE(os.stat(probe_daemon.control_path).st_mode) == 0o600
    with serial.Serial(by_device["probe"]["path"], 9600, timeout=2) as port:
        assert ask(port, b"E hello\r", 6) == b"hello\r"


def test_pacing_at_9600_delivers_100_bytes_in_104_ms(probe_daemon: RunningDaemon) -> None:
    with serial.Serial(probe_daemon.port("probe"), 9600, timeout=2) as port:
        command = b"B 100\r"
        ask(port, b"E warm\r", 5)
        start = time.monotonic()
        port.write(command)
        data = port.read(100)
        elapsed = time.monotonic() - start - len(command) * CHAR_9600
    assert data == b"x" * 100
    # 100 characters of 10 bits at 9600 baud: 104.2 ms; ±10 % covers scheduling on a busy machine.
    assert elapsed == pytest.approx(100 * CHAR_9600, rel=0.10)


def test_fast_timing_is_immediate(probe_daemon: RunningDaemon) -> None:
    with serial.Serial(probe_daemon.port("fast"), 9600, timeout=2) as port:
        ask(port, b"E warm\r", 5)
        start = time.monotonic()
        data = ask(port, b"B 100\r", 100)
        elapsed = time.monotonic() - start
    assert data == b"x" * 100
    # Unpaced, the whole exchange is scheduler-bound: far below the 104 ms the wire would take.
    assert elapsed < 0.05


def test_host_settings_are_seen_by_the_device(probe_daemon: RunningDaemon) -> None:
    client = probe_daemon.control()
    with serial.Serial(probe_daemon.port("probe"), 19200, stopbits=2, rtscts=True, timeout=2) as port:
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


def test_200_attach_detach_cycles_leak_nothing(probe_daemon: RunningDaemon) -> None:
    client = probe_daemon.control()
    path = probe_daemon.port("fast")

    def settled_fd_count() -> int:
        # the daemon handles a hang-up asynchronously and briefly holds a peer fd to flush stale output
        while attached(client, "fast"):
            pass
        return fd_count(probe_daemon.proc.pid)

    with serial.Serial(path, 9600, timeout=2) as port:
        assert ask(port, b"E first\r", 6) == b"first\r"
    before = settled_fd_count()
    for i in range(200):
        with serial.Serial(path, 9600, timeout=2) as port:
            assert ask(port, f"E {i}\r".encode(), len(str(i)) + 1) == f"{i}\r".encode()
    assert settled_fd_count() == before
    assert probe_daemon.proc.poll() is None


def test_unread_output_does_not_reach_the_next_opener(probe_daemon: RunningDaemon) -> None:
    client = probe_daemon.control()
    path = probe_daemon.port("fast")
    with serial.Serial(path, 9600, timeout=2) as port:
        port.write(b"E stale\r")
        port.flush()
        while client.snapshot("fast", "lines") < 1:
            port.read(0)  # the reply is queued once the device has counted the line
    while attached(client, "fast"):
        pass  # the daemon handles the hang-up asynchronously
    # A naive opener (no flush on open, unlike pyserial) must not see the departed host's reply.
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, b"E fresh\r")
        assert select.select([fd], [], [], 2)[0], "no reply"
        assert os.read(fd, 100) == b"fresh\r"
    finally:
        os.close(fd)


def attached(client: ControlClient, device: str) -> bool:
    listing = {d["device"]: d for d in client.list()}
    return listing[device]["ports"][0]["attached"]


def test_idle_daemon_does_not_spin(probe_daemon: RunningDaemon) -> None:
    with serial.Serial(probe_daemon.port("probe"), 9600, timeout=2) as port:
        ask(port, b"E x\r", 2)
    ticks = os.sysconf("SC_CLK_TCK")

    def cpu() -> float:
        fields = Path(f"/proc/{probe_daemon.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / ticks

    before = cpu()
    ControlClient(probe_daemon.control_path).close()
    time.sleep(1.0)  # measuring idleness needs elapsed time; nothing to wait for
    assert cpu() - before < 0.1


def test_sigterm_removes_links_and_socket(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", str(PROBE)], expect_ports=1, test_devices=True)
    link = Path(daemon.ports[0]["path"])
    assert link.is_symlink() and daemon.control_path.exists()
    assert daemon.stop(signal.SIGTERM) == 0
    assert not link.exists() and not link.is_symlink()
    assert not daemon.control_path.exists()


def test_sigint_exits_zero(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", str(PROBE)], expect_ports=1, test_devices=True)
    assert daemon.stop(signal.SIGINT) == 0


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
        timeout=30,
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


def test_control_round_trips(probe_daemon: RunningDaemon) -> None:
    client = probe_daemon.control()
    events = probe_daemon.control()
    assert events.subscribe("fast") is True
    with serial.Serial(probe_daemon.port("fast"), 9600, timeout=2) as port:
        assert ask(port, b"E one\r", 4) == b"one\r"
        assert client.input("fast", "say", text="hi") is True
        assert port.read(2) == b"hi"
        assert client.snapshot("fast", "lines") == 1
        assert client.fault("fast", "drop", count=1)["drop_replies"] == 1
        port.write(b"E dropped\r")
        assert ask(port, b"E kept\r", 5) == b"kept\r"
    assert [e["text"] for e in events.events(timeout=1.0)][:3] == ["E one", "E dropped", "E kept"]
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
    with pytest.raises(ControlFailure):
        probe_daemon.control().request({"op": "nope"})
    assert probe_daemon.control().list()


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
        with serial.Serial(daemon.port("probe"), 9600, timeout=5) as port:
            start = time.monotonic()
            assert ask(port, b"D 2000 done\r", 5) == b"done\r"
            # 2 s of device time at 20x: 0.1 s of wall time (generous bound for a loaded machine)
            assert time.monotonic() - start < 1.0
    finally:
        assert daemon.stop() == 0
    assert not ready.exists()
    records = [json.loads(line) for line in traffic.read_text().splitlines()]
    entries = [e for e in records if e["dir"] != "ev"]  # the probe's `line` events are logged too
    assert [(e["dir"], bytes.fromhex(e["hex"])) for e in entries] == [
        ("rx", b"D 2000 done\r"),
        ("tx", b"done\r"),
    ]
    assert entries[1]["t"] - entries[0]["t"] == pytest.approx(2.0, abs=0.05)
