"""A daemon with many idle ports, and MS2000 settings surviving a daemon killed with SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import serial

from tests.support.daemon import start_daemon

IDLE_PORTS = 64
#: generous: only a hang takes this long on any machine
HANG_S = 10.0


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_64_idle_ports_use_almost_no_cpu(tmp_path: Path) -> None:
    devices = [
        {"name": f"{family}{i}", "profile": family}
        for i in range(IDLE_PORTS // 2)
        for family in ("mp285", "ms2000")
    ]
    rig = tmp_path / "rig.yaml"
    rig.write_text(json.dumps({"spec": 1, "devices": devices}))
    daemon = start_daemon(tmp_path, [str(rig)], expect_ports=IDLE_PORTS)
    try:
        before = cpu_seconds(daemon.proc.pid)
        time.sleep(2.0)  # idleness is measured over elapsed time; there is no event to wait for
        used = cpu_seconds(daemon.proc.pid) - before
        # near 0 %: under 2.5 % of one core, allowing a few scheduler ticks of noise
        assert used < 0.05, f"{used:.3f} s of CPU in 2 s with {IDLE_PORTS} idle ports"
    finally:
        assert daemon.stop() == 0


def ask(port: serial.Serial, line: bytes) -> bytes:
    port.write(line)
    return port.read_until(b"\r\n")


def test_saved_settings_survive_sigkill_and_a_corrupt_file_is_set_aside(tmp_path: Path) -> None:
    """MS2000 `SS Z` writes the state file atomically; a restart after SIGKILL reloads it."""
    args = ["--profile", "ms2000", "--timing", "fast"]
    daemon = start_daemon(tmp_path, args, expect_ports=1)
    with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as port:
        assert ask(port, b"S X=2.5\r") == b":A\r\n"
        assert ask(port, b"SS Z\r") == b":A\r\n"
    assert daemon.stop(signal.SIGKILL) == -signal.SIGKILL

    daemon = start_daemon(tmp_path, args, expect_ports=1)
    with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as port:
        assert ask(port, b"S X?\r") == b":A X=2.500000\r\n"
    assert daemon.stop() == 0

    (state,) = (tmp_path / "state").glob("*.json")
    state.write_text("{ not json")
    daemon = start_daemon(tmp_path, args, expect_ports=1)
    try:
        with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as port:
            assert ask(port, b"S X?\r") == b":A X=5.145600\r\n"  # factory speed
    finally:
        assert daemon.stop() == 0
    assert "corrupt" in daemon.stderr()
    assert len(list((tmp_path / "state").glob("*.corrupt-*"))) == 1


def test_sigterm_right_after_a_save_loses_nothing(tmp_path: Path) -> None:
    """Saves are written off the event loop; a clean stop (SIGTERM) writes the last one before it
    exits. `SL` is remembered at once and, unlike `SS Z`, acks without waiting for the disk (MS-111)."""
    args = ["--profile", "ms2000", "--timing", "fast"]
    daemon = start_daemon(tmp_path, args, expect_ports=1)
    with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as port:
        for value in range(-50, -40):
            assert ask(port, f"SL X={value}\r".encode()) == b":A\r\n"
    assert daemon.stop() == 0

    (state,) = (tmp_path / "state").glob("*.json")
    assert json.loads(state.read_text())["auto"]["axes"]["X"]["soft_lower"] == -41.0
    daemon = start_daemon(tmp_path, args, expect_ports=1)
    try:
        with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as port:
            assert ask(port, b"SL X?\r") == b":A X=-41.000\r\n"
    finally:
        assert daemon.stop() == 0
