"""The daemon's life at its edges: one daemon at a time owns a device's non-volatile memory, and
stopping it with control clients connected is clean on both sides (no traceback in the daemon,
one line and exit 1 from `stage-emu ctl watch`)."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (registers the stageemu:// scheme)
from emulator.control_client import ControlClient
from emulator.hosting.launcher import write_rig
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

CLI = [sys.executable, "-m", "emulator.cli"]
MS2000 = ["--profile", "ms2000", "--timing", "fast"]
ACK = b":A\r\n"


def env(tmp_path: Path) -> dict[str, str]:
    """One user's session: every daemon of the test shares this runtime directory."""
    run = tmp_path / "run"
    run.mkdir(exist_ok=True, mode=0o700)
    return {**os.environ, "PYTHONPATH": str(ROOT), "XDG_RUNTIME_DIR": str(run)}


def ms2000(workdir: Path, tmp_path: Path) -> RunningDaemon:
    """An MS2000 daemon with its links, socket and state under `workdir`."""
    return start_daemon(workdir, MS2000, expect_ports=1, env=env(tmp_path))


def ask(path: str, *commands: bytes) -> list[bytes]:
    with serial.Serial(path, 9600, timeout=5) as port:
        replies = []
        for command in commands:
            port.write(command)
            replies.append(port.read_until(b"\r\n"))
        return replies


# ---- one owner per non-volatile memory ---------------------------------------------------------


def test_a_second_daemon_on_the_same_memory_is_refused_and_the_first_keeps_its_save(tmp_path: Path) -> None:
    """The README's two-daemon recipe, on one state directory: the second used to start, and its
    `SS Z` silently replaced the first's."""
    first = ms2000(tmp_path / "a", tmp_path)
    state = tmp_path / "a" / "state"
    try:
        assert ask(first.port("ms2000"), b"S X=2\r", b"SS Z\r") == [ACK, ACK]
        own_paths = ["--control", str(tmp_path / "b.sock"), "--link-dir", str(tmp_path / "b-links")]
        second = subprocess.run(
            [*CLI, "serve", *MS2000, "--state-dir", str(state), *own_paths],
            cwd=ROOT,
            env=env(tmp_path),
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert second.returncode == 1 and second.stdout == "", second.stderr
        (line,) = second.stderr.splitlines()
        assert line == (
            f"stage-emu: ms2000: non-volatile memory {state / 'ms2000-0001.json'} is in use by another "
            f"stage-emu (pid {first.proc.pid}); give this daemon its own --state-dir DIR, or --no-state "
            "to keep its devices' memory for this run only"
        )
        assert not (tmp_path / "b.sock").exists() and not (tmp_path / "b-links" / "ms2000").exists()
        assert ask(first.port("ms2000"), b"S X?\r") == [b":A X=2.000000\r\n"]
    finally:
        assert first.stop() == 0
    assert "Traceback" not in first.stderr()
    again = ms2000(tmp_path / "a", tmp_path)  # the same memory, once its owner has stopped
    try:
        assert ask(again.port("ms2000"), b"S X?\r") == [b":A X=2.000000\r\n"]
    finally:
        assert again.stop() == 0


def test_a_killed_owner_does_not_block_the_next_start(tmp_path: Path) -> None:
    first = ms2000(tmp_path / "a", tmp_path)
    assert ask(first.port("ms2000"), b"S X=4\r", b"SS Z\r") == [ACK, ACK]
    first.stop(signal.SIGKILL)  # its lock dies with it
    second = ms2000(tmp_path / "a", tmp_path)
    try:
        assert ask(second.port("ms2000"), b"S X?\r") == [b":A X=4.000000\r\n"]
    finally:
        assert second.stop() == 0


def test_the_url_respects_the_daemons_ownership_and_the_daemon_the_urls(tmp_path: Path) -> None:
    """`stageemu://...?state=DIR` goes through the same store: it cannot take a daemon's memory, and
    a daemon cannot take the memory of a program whose port is open."""
    daemon = ms2000(tmp_path / "a", tmp_path)
    state = tmp_path / "a" / "state"
    memory = state / "ms2000-0001.json"
    url = f"stageemu://ms2000?timing=fast&state={state}"
    try:
        with pytest.raises(ValueError) as refused:
            serial.serial_for_url(url, baudrate=9600)
        assert str(refused.value) == (
            f"{url!r}: non-volatile memory {memory} is in use by process {daemon.proc.pid}; "
            "give state= another directory, or none"
        )
    finally:
        assert daemon.stop() == 0
    port = serial.serial_for_url(url, baudrate=9600)
    try:
        with pytest.raises(RuntimeError, match=rf"in use by another stage-emu \(pid {os.getpid()}\)"):
            ms2000(tmp_path / "a", tmp_path)
    finally:
        port.close()
    after = ms2000(tmp_path / "a", tmp_path)  # closing the port gave its claim up
    assert after.stop() == 0


def test_no_state_runs_beside_the_owner_and_saves_nothing(tmp_path: Path) -> None:
    """`--no-state`: the way out the refusal names, memory for this run only."""
    first = ms2000(tmp_path / "a", tmp_path)
    state = tmp_path / "a" / "state"
    try:
        assert ask(first.port("ms2000"), b"S X=2\r", b"SS Z\r") == [ACK, ACK]
        saved = (state / "ms2000-0001.json").read_text()
        home = {**env(tmp_path), "XDG_STATE_HOME": str(tmp_path / "home-state")}
        second = start_daemon(tmp_path / "b", [*MS2000, "--no-state"], expect_ports=1, env=home)
        try:
            speed, *acks = ask(second.port("ms2000"), b"S X?\r", b"S X=3\r", b"SS Z\r")
            assert speed != b":A X=2.000000\r\n", "factory settings, not the owner's save"
            assert acks == [ACK, ACK]
        finally:
            assert second.stop() == 0
        assert (state / "ms2000-0001.json").read_text() == saved
        assert not (tmp_path / "home-state").exists() and not (tmp_path / "b" / "state").exists()
        assert ask(first.port("ms2000"), b"S X?\r") == [b":A X=2.000000\r\n"]
    finally:
        assert first.stop() == 0


def test_no_state_and_a_state_dir_are_refused_together(tmp_path: Path) -> None:
    refused = subprocess.run(
        [*CLI, "serve", *MS2000, "--no-state", "--state-dir", str(tmp_path)],
        cwd=ROOT,
        env=env(tmp_path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert refused.returncode == 1
    assert refused.stderr == "stage-emu: give --state-dir or --no-state, not both\n"


def test_two_devices_of_one_rig_on_one_memory_are_told_once(tmp_path: Path) -> None:
    """Two devices of one profile share its device_id, so one file: said at start, not silently."""
    rig = write_rig(tmp_path, [("left", "ms2000"), ("right", "ms2000"), ("other", "mp285")], "fast")
    daemon = start_daemon(tmp_path, [str(rig)], expect_ports=3, env=env(tmp_path))
    try:
        ask(daemon.port("right"), b"SS Z\r")
        daemon.control().reset("right")  # a new model opens its memory again: nothing more said
    finally:
        assert daemon.stop() == 0
    shared = [line for line in daemon.stderr().splitlines() if "share one non-volatile memory" in line]
    assert shared == [
        "stage-emu: left and right share one non-volatile memory (device_id ms2000-0001): each one's "
        "saves overwrite the other's; give each its own device_id in its profile or rig overrides"
    ]


# ---- stopping with control clients connected ---------------------------------------------------


@pytest.fixture
def watched(tmp_path: Path) -> Iterator[tuple[RunningDaemon, subprocess.Popen[str]]]:
    """A daemon with `stage-emu ctl watch --traffic` attached (it has printed a record)."""
    daemon = ms2000(tmp_path, tmp_path)
    watch = subprocess.Popen(
        [*CLI, "ctl", "--control", str(daemon.control_path), "watch", "ms2000", "--traffic"],
        cwd=ROOT,
        env=env(tmp_path),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert watch.stdout is not None
        # the watch prints nothing until it is subscribed and the device talks: talk until it does
        done = threading.Event()

        def talk() -> None:
            while not done.is_set():
                ask(daemon.port("ms2000"), b"W X\r")

        talker = threading.Thread(target=talk)
        talker.start()
        try:
            # generous, the watch's start included: only a hang takes this long
            assert select.select([watch.stdout], [], [], 60)[0], "`ctl watch` printed nothing"
            record = json.loads(watch.stdout.readline())
        finally:
            done.set()
            talker.join(30)
        assert record["ev"] == "traffic" and record["device"] == "ms2000"
        yield daemon, watch
    finally:
        if daemon.proc.poll() is None:
            daemon.stop(signal.SIGKILL)
        if watch.poll() is None:
            watch.kill()
        watch.communicate(timeout=30)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_stopping_with_clients_connected_is_clean_and_ctl_watch_says_one_line(
    watched: tuple[RunningDaemon, subprocess.Popen[str]], sig: signal.Signals
) -> None:
    """SIGTERM (or the terminal closing: SIGHUP) with a subscriber, a client mid-request and
    `ctl watch` attached: the daemon printed a CancelledError traceback per connection, and
    `ctl watch` a ConnectionError traceback."""
    daemon, watch = watched
    subscriber = ControlClient(daemon.control_path)
    subscriber.subscribe("ms2000")
    mid_request = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    mid_request.connect(str(daemon.control_path))
    mid_request.sendall(b'{"id": 1, "op": "li')
    try:
        assert subscriber.list()  # the daemon has taken both connections in
        assert daemon.stop(sig) == 0
        _, stderr = watch.communicate(timeout=30)
    finally:
        subscriber.close()
        mid_request.close()
    assert "Traceback" not in daemon.stderr(), daemon.stderr()
    assert watch.returncode == 1
    assert stderr.splitlines() == ["stage-emu: lost the daemon: control channel closed"], stderr
