"""Hosts that do not play by the wire's rules: one writing at full speed into a 9600-baud port, one
writing commands without ever reading. The daemon stays bounded in memory, takes input no faster
than the emulated line carries it, keeps serving its other ports, and counts what it dropped."""

from __future__ import annotations

import os
import select
import termios
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import serial

from emulator.control_client import ControlClient
from tests.support.daemon import RunningDaemon, start_daemon

RIG = """spec: 1
devices:
  - name: flooded
    profile: ms2000
  - name: neighbour
    profile: ms2000
  - name: stage
    profile: mp285
  - name: unread
    profile: ms2000
    ports: [{timing: fast}]
"""
#: what the daemon may take on top of its own start-up footprint while being abused
RSS_GROWTH_LIMIT = 10 * 1024 * 1024
#: a reply on a quiet port while another floods, or any awaited condition: generous, only a hang
#: takes this long on any machine
REPLY_TIMEOUT = 10.0
#: the MS2000's answer to `V`
VERSION = b":A Version: USB-9.2k \r\n"
#: output the host that never reads makes the daemon drop
DROPPED = 64 * 1024
#: round trips the neighbours answer while the flooded port refuses its writer
ROUNDS = 5


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    workdir = tmp_path_factory.mktemp("backpressure")
    rig = workdir / "rig.yaml"
    rig.write_text(RIG)
    running = start_daemon(workdir, [str(rig)], expect_ports=4)
    yield running
    assert running.stop() == 0


def rss(daemon: RunningDaemon) -> int:
    for line in Path(f"/proc/{daemon.proc.pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


@contextmanager
def raw_host(path: str) -> Iterator[int]:
    """A host that opens the port non-blocking at 9600 baud and never reads unless told to."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = termios.B9600
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
        yield fd
    finally:
        os.close(fd)


def write_until(
    fd: int, chunk: Callable[[int], bytes], done: Callable[[], bool], refused: threading.Event | None = None
) -> tuple[int, int | None]:
    """Write `chunk(offset)` as fast as the port takes it until `done()`; returns the bytes it took
    and how many it had taken when it first refused (EAGAIN, then `refused` is set), or None if it
    never did."""
    taken, first_refusal = 0, None
    deadline = time.monotonic() + REPLY_TIMEOUT * 6
    while not done():
        assert time.monotonic() < deadline, f"still not done after {taken} bytes"
        try:
            taken += os.write(fd, chunk(taken))
        except BlockingIOError:
            first_refusal = taken if first_refusal is None else first_refusal
            if refused is not None:
                refused.set()
            select.select([], [fd], [], 0.05)
    return taken, first_refusal


def write_some(fd: int, data: bytes) -> int:
    """What of `data` the port takes now (0 when it has no room after all)."""
    try:
        return os.write(fd, data)
    except BlockingIOError:
        return 0


def dropped(client: ControlClient, device: str) -> int:
    return int(port_stats(client, device)["stats"]["output_dropped"])


def port_stats(client: ControlClient, device: str) -> dict[str, Any]:
    device_entry = next(d for d in client.list() if d["device"] == device)
    return device_entry["ports"][0]


def wait_for(condition: Callable[[], bool]) -> None:
    """Until `condition()` (each check a control request: the daemon's answer paces the loop)."""
    deadline = time.monotonic() + REPLY_TIMEOUT
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"


def test_full_speed_writer_is_paced_and_other_ports_keep_answering(daemon: RunningDaemon) -> None:
    before = rss(daemon)
    flood = os.urandom(2 * 1024 * 1024)
    result: list[tuple[int, int | None]] = []
    stop, refused = threading.Event(), threading.Event()
    with raw_host(daemon.port("flooded")) as fd:
        writer = threading.Thread(
            target=lambda: result.append(
                write_until(fd, lambda at: flood[at : at + 65536], stop.is_set, refused)
            )
        )
        writer.start()
        try:
            with (
                serial.Serial(daemon.port("neighbour"), 9600, timeout=REPLY_TIMEOUT) as ms2000,
                serial.Serial(daemon.port("stage"), 9600, timeout=REPLY_TIMEOUT) as mp285,
            ):
                ms2000.write(b"W X\r")
                expected_x = ms2000.read_until(b"\r\n")
                assert expected_x == b":A 0\r\n"
                mp285.write(b"c\r")
                expected_c = mp285.read(13)
                assert len(expected_c) == 13 and expected_c.endswith(b"\r")
                # the neighbours answer while the flooded port holds its writer back
                rounds = 0
                while rounds < ROUNDS or not refused.is_set():
                    assert writer.is_alive(), result
                    ms2000.write(b"W X\r")
                    assert ms2000.read_until(b"\r\n") == expected_x
                    mp285.write(b"c\r")
                    assert mp285.read(13) == expected_c
                    rounds += 1
        finally:
            stop.set()
            writer.join()
        taken, first_refusal = result[0]
        # The kernel holds ~12 KiB, the daemon 4 KiB, and the wire carries 960 bytes/s meanwhile.
        assert first_refusal is not None and first_refusal < 64 * 1024, result
        assert taken < 64 * 1024, result
        assert rss(daemon) - before < RSS_GROWTH_LIMIT
    # The host hung up while the port was not reading: seen all the same, the rest discarded.
    with ControlClient(daemon.control_path) as client:
        wait_for(lambda: not port_stats(client, "flooded")["attached"])
        assert port_stats(client, "flooded")["stats"]["input_discarded"] > 0


def test_host_that_never_reads_loses_output_and_is_answered_after_reading(daemon: RunningDaemon) -> None:
    before = rss(daemon)
    commands = b"W X\r" * 1024
    with raw_host(daemon.port("unread")) as fd, ControlClient(daemon.control_path) as client:
        # whole commands, even after a short write, until the port has dropped far more output than
        # every buffer between the device and the host holds (the kernel's ~18 KiB, its own 4 KiB)
        write_until(fd, lambda at: commands[at % 4 :], lambda: dropped(client, "unread") >= DROPPED)
        assert rss(daemon) - before < RSS_GROWTH_LIMIT
        termios.tcflush(fd, termios.TCIFLUSH)
        # What the daemon still held may come after the flush: the answer to a command whose reply
        # differs from theirs ends whatever arrives, at whatever moment the held replies do. Commands
        # the daemon has not taken yet (a loaded machine) may leave no room for `V` at first: read
        # while waiting for room, or their replies would fill the way back and the port drop `V`'s.
        reply, unsent = b"", b"V\r"
        while not reply.endswith(VERSION):
            readable, writable, _ = select.select([fd], [fd] if unsent else [], [], REPLY_TIMEOUT)
            assert readable or writable, f"no reply, got {reply!r}"
            if writable:
                unsent = unsent[write_some(fd, unsent) :]
            if readable:
                reply += os.read(fd, 65536)
        held = reply[: -len(VERSION)].replace(b":A 0\r\n", b"")
        assert b":A 0\r\n".endswith(held), reply  # whole replies, the first maybe cut by the flush
