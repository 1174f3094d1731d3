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
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial
from rich.console import Console

from emulator.cli.view import full_refresh, render, update
from emulator.control_client import ControlClient
from emulator.tools.view import ViewState
from protocols.clients import MS2000
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

DEVICE = "ms2000"
WATCH = ("watch", DEVICE, "--traffic")
#: generous: only a hang takes this long on any machine
HANG_S = 10.0
#: a command's whole run, its start included: generous, a loaded machine has taken ten seconds to
#: start a Python process
RUN_S = 60.0


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    """A daemon without a traffic log, for the tests that only talk to it."""
    daemon = start_daemon(tmp_path_factory.mktemp("view"), ["--profile", DEVICE], expect_ports=1)
    yield daemon
    assert daemon.stop() == 0, daemon.stderr()


@pytest.fixture
def daemon(served: RunningDaemon) -> RunningDaemon:
    with ControlClient(served.control_path) as client:
        client.reset(DEVICE)
    return served


def test_one_event_updates_the_device(tmp_path: Path) -> None:
    log = tmp_path / "traffic.jsonl"
    daemon = start_daemon(tmp_path, ["--profile", DEVICE, "--log-traffic", str(log)], expect_ports=1)
    try:
        client = daemon.control()
        state = ViewState()
        full_refresh(client, state, set())
        assert state.traffic_log == str(log.resolve())
        assert state.devices[DEVICE].positions.startswith("X=0.0000mm")
        with MS2000(daemon.port(DEVICE), 9600, timeout=HANG_S) as stage:
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


def test_a_host_command_is_shown_decoded(daemon: RunningDaemon) -> None:
    with ControlClient(daemon.control_path) as client:
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


def test_the_daemon_going_away_is_one_line_and_exit_1(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", DEVICE], expect_ports=1)
    screen, terminal = os.openpty()  # a terminal for the view to draw on, and the test to read
    view = subprocess.Popen(
        [sys.executable, "-m", "emulator.cli", "view", "--control", str(daemon.control_path)],
        stdout=terminal,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "120", "LINES": "40"},
        text=True,
    )
    os.close(terminal)
    drawn = Screen(screen)
    try:
        # the device's panel is on the screen: the view has read the daemon and is in its live loop
        assert drawn.wait_for(DEVICE), (drawn.text(), view.poll())
        assert view.poll() is None
    finally:
        assert daemon.stop() == 0
    _, err = view.communicate(timeout=RUN_S)
    drawn.join(RUN_S)
    assert view.returncode == 1
    assert err.count("\n") == 1 and err.startswith("stage-emu: lost the daemon"), err


class Screen(threading.Thread):
    """Everything a program writes to the terminal whose other side is `fd` (read until it closes,
    so the program never blocks on a full terminal)."""

    def __init__(self, fd: int) -> None:
        super().__init__(daemon=True, name="view-screen")
        self._fd = fd
        self._seen = b""
        self._changed = threading.Condition()
        self.start()

    def run(self) -> None:
        try:
            while chunk := os.read(self._fd, 65536):
                with self._changed:
                    self._seen += chunk
                    self._changed.notify_all()
        except OSError:  # EIO: the program closed the terminal
            pass
        finally:
            os.close(self._fd)

    def text(self) -> str:
        with self._changed:
            return self._seen.decode("utf-8", "replace")

    def wait_for(self, needle: str) -> bool:
        with self._changed:
            return self._changed.wait_for(lambda: needle.encode() in self._seen, RUN_S)


def test_ctl_watch_traffic_prints_the_records(daemon: RunningDaemon) -> None:
    """`stage-emu ctl watch DEVICE --traffic`: the traffic records, one JSON line each, with no log."""
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
            deadline = time.monotonic() + RUN_S
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
        watch.wait(timeout=RUN_S)
