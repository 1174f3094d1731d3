"""`stage-emu view` against a running daemon: one pass of its update function after a move (the
event marks the device stale and its snapshot is read again), a host's command shown decoded from
the traffic records the view subscribes to (the daemon keeps no traffic log), and the live command
exiting with one line and status 1 when the daemon goes away."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import serial
from rich.console import Console

from emulator.cli_view import full_refresh, render, update
from emulator.view import ViewState
from protocols.clients import MS2000
from tests.support.daemon import ROOT, start_daemon

DEVICE = "ms2000"
WATCH = ("watch", DEVICE, "--traffic")


def test_one_event_updates_the_device(tmp_path: Path) -> None:
    log = tmp_path / "traffic.jsonl"
    daemon = start_daemon(tmp_path, ["--profile", DEVICE, "--log-traffic", str(log)], expect_ports=1)
    try:
        client = daemon.control()
        state = ViewState()
        full_refresh(client, state, set())
        assert state.traffic_log == str(log.resolve())
        assert state.devices[DEVICE].positions.startswith("X=0.0000mm")
        with MS2000(daemon.port(DEVICE), 9600) as stage:
            stage.move(X=1000)
            stage.wait_until_idle()
            assert state.devices[DEVICE].ports[0].attached == "no"  # not re-read without an event
            stale: set[str] = set()
            deadline = time.monotonic() + 10
            while not any(e.split()[1:2] == ["move_complete"] for e in state.devices[DEVICE].events):
                assert time.monotonic() < deadline, list(state.devices[DEVICE].events)
                stale |= update(client, state, timeout=1.0)
        assert stale == {DEVICE}
        assert state.devices[DEVICE].positions.startswith("X=0.1000mm")
        assert state.devices[DEVICE].busy == "idle"
    finally:
        assert daemon.stop() == 0


def test_a_host_command_is_shown_decoded(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", DEVICE], expect_ports=1)
    try:
        client = daemon.control()
        state = ViewState()
        full_refresh(client, state, set())
        assert state.traffic_log is None
        with serial.Serial(daemon.port(DEVICE), 9600, timeout=5) as host:
            host.write(b"W X Y\r")
            assert host.read_until(b"\n") == b":A 0 0\r\n"
        deadline = time.monotonic() + 10
        while not state.devices[DEVICE].exchanges:
            assert time.monotonic() < deadline, "no exchange shown"
            update(client, state, timeout=1.0)
        row = state.devices[DEVICE].exchanges[0]
        assert (row.port, row.flag, row.request, row.reply) == ("main", "", "W X Y [WHERE]", '":A 0 0\\r\\n"')
        console = Console(record=True, width=120)
        console.print(render(state))
        assert 'W X Y [WHERE] -> ":A 0 0\\r\\n"' in " ".join(console.export_text().split())
    finally:
        assert daemon.stop() == 0


def test_the_daemon_going_away_is_one_line_and_exit_1(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", DEVICE], expect_ports=1)
    view = subprocess.Popen(
        [sys.executable, "-m", "emulator.cli", "view", "--control", str(daemon.control_path)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        text=True,
    )
    try:
        deadline = time.monotonic() + 15
        while not _has_socket(view.pid):  # connected to the control channel
            assert view.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.5)  # its first full refresh
        assert view.poll() is None
    finally:
        assert daemon.stop() == 0
    _, err = view.communicate(timeout=10)
    assert view.returncode == 1
    assert err.count("\n") == 1 and err.startswith("stage-emu: lost the daemon"), err


def _has_socket(pid: int) -> bool:
    fds = Path(f"/proc/{pid}/fd")
    try:
        return any(os.readlink(fd).startswith("socket:") for fd in fds.iterdir())
    except OSError:
        return False


def test_ctl_watch_traffic_prints_the_records(tmp_path: Path) -> None:
    """`stage-emu ctl watch DEVICE --traffic`: the traffic records, one JSON line each, with no log."""
    daemon = start_daemon(tmp_path, ["--profile", DEVICE], expect_ports=1)
    watch = subprocess.Popen(
        [sys.executable, "-m", "emulator.cli", "ctl", "--control", str(daemon.control_path), *WATCH],
        stdout=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        text=True,
    )
    try:
        assert watch.stdout is not None
        records: list[dict[str, object]] = []
        with serial.Serial(daemon.port(DEVICE), 9600, timeout=5) as host:
            deadline = time.monotonic() + 15
            while not records:  # until the watch has subscribed, a command goes unrecorded
                assert time.monotonic() < deadline and watch.poll() is None, "no traffic record"
                host.write(b"W X Y\r")
                assert host.read_until(b"\n") == b":A 0 0\r\n"
                if select.select([watch.stdout], [], [], 0.2)[0]:
                    records.append(json.loads(watch.stdout.readline()))
        assert records[0]["ev"] == "traffic" and records[0]["device"] == DEVICE
        assert (records[0]["dir"], records[0]["kind"], records[0]["summary"]) == (
            "rx",
            "frame",
            "W X Y [WHERE]",
        )
    finally:
        watch.terminate()
        watch.wait(timeout=10)
        assert daemon.stop() == 0
