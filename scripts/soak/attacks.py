"""The torture suite's attacks. Each starts its own daemon, attacks it, measures it from outside and
returns an `Outcome`: figures, and the bounds it exceeded (none = passed).

Bounds (issue "Hardening"): a flood of random bytes into every port grows the daemon by < 10 MB and
keeps the other ports' p99 within 1.2x idle; open/close cycles leave fds and RSS flat and no CPU
use after; a subscriber that never reads costs a bounded amount of memory.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import random
import select
import signal
import socket
import struct
import termios
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import serial

from emulator.control_client import ControlClient
from emulator.hosting.launcher import RunningDaemon, start_daemon, write_rig
from scripts.soak.probes import Latencies, cpu_percent, fd_count, round_trips, rss_mb, settle

MEASURED = "measured"
W_X = (b"W X\r", b":A 0\r\n")
#: growth allowed while attacked, in MB
RSS_GROWTH_MB = 10.0
P99_RATIO = 1.2
#: an idle daemon's CPU use (percent of one core) that still counts as idle
IDLE_CPU_PERCENT = 1.0


@dataclass
class Outcome:
    attack: str
    figures: dict[str, Any] = field(default_factory=dict)
    exceeded: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.exceeded

    def bound(self, ok: bool, text: str) -> None:
        if not ok:
            self.exceeded.append(text)


def _start(workdir: Path, devices: list[tuple[str, str]], timing: str, *extra: str) -> RunningDaemon:
    rig = write_rig(workdir, devices, timing)
    return start_daemon(workdir, [str(rig), *extra], expect_ports=len(devices))


@dataclass
class _Siege:
    """A host's `W X` round trips on a neighbour port before, during and after an attack."""

    idle: Latencies
    busy: Latencies
    still: Latencies
    rss_before_mb: float
    rss_after_mb: float
    #: bytes the attacker got the daemon (and the kernel buffers in front of it) to take
    accepted: int

    def figures(self) -> dict[str, Any]:
        return {
            "bytes_accepted": self.accepted,
            "rss_before_mb": self.rss_before_mb,
            "rss_after_mb": self.rss_after_mb,
            "idle_p99_ms": self.idle.p99,
            "flood_p99_ms": self.busy.p99,
            "p99_ratio": self.busy.p99 / self.idle.p99,
        }

    def bound(self, out: Outcome) -> None:
        growth = self.rss_after_mb - self.rss_before_mb
        out.bound(growth < RSS_GROWTH_MB, f"RSS grew by >= {RSS_GROWTH_MB} MB")
        out.bound(self.busy.p99 <= P99_RATIO * self.idle.p99, f"other port's p99 > {P99_RATIO}x idle")
        out.bound(bool(self.still.samples), "measured port stopped answering")


def _siege(
    daemon: RunningDaemon, attack: Callable[..., None], targets: list[str], seconds: float, idle_trips: int
) -> _Siege:
    """Round trips on the MEASURED port while `attack(targets, seconds, seed, counter)` runs in a
    child process."""
    pid = daemon.proc.pid
    with serial.Serial(daemon.port(MEASURED), 9600, timeout=5) as port:
        idle = round_trips(port, *W_X, count=idle_trips)
        before = rss_mb(pid)
        counter = multiprocessing.Value("q", 0)
        attacker = multiprocessing.Process(target=attack, args=(targets, seconds, 2026, counter))
        attacker.start()
        busy = round_trips(port, *W_X, count=idle_trips, until=time.monotonic() + seconds)
        attacker.join()
        after = rss_mb(pid)
        still = round_trips(port, *W_X, count=10)
    return _Siege(idle, busy, still, before, after, counter.value)


def _flood(paths: list[str], seconds: float, seed: int, counter: Any) -> None:
    """Child process: write random bytes at full speed into every port, never reading."""
    rng = random.Random(seed)
    fds = []
    for path in paths:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd)
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = termios.B9600
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
        fds.append(fd)
    chunk = rng.randbytes(4096)
    end = time.monotonic() + seconds
    written = 0
    while (left := end - time.monotonic()) > 0:
        _, ready, _ = select.select([], fds, [], left)
        for fd in ready:
            try:
                written += os.write(fd, chunk)
            except BlockingIOError:
                continue
    counter.value = written
    for fd in fds:
        os.close(fd)


def flood(workdir: Path, seconds: float = 60.0, flooded: int = 6, idle_trips: int = 300) -> Outcome:
    """Random bytes at full speed into `flooded` realistic 9600-baud ports (MP-285s and MS2000s)
    while a host does `W X` round trips on another MS2000 port of the same daemon."""
    out = Outcome("flood: random bytes at full speed into every port")
    devices = [(MEASURED, "ms2000")] + [(f"flood{i}", "ms2000" if i % 2 else "mp285") for i in range(flooded)]
    daemon = _start(workdir, devices, "realistic")
    try:
        paths = [daemon.port(name) for name, _ in devices[1:]]
        siege = _siege(daemon, _flood, paths, seconds, idle_trips)
        out.figures.update(
            ports=flooded,
            seconds=seconds,
            **siege.figures(),
            cpu_after_percent=cpu_percent(daemon.proc.pid, 2.0),
        )
        # what the wires carry at 960 characters/s, plus what kernel buffers absorb (< 1 MiB a port)
        wire = flooded * (seconds * 960 + (1 << 20))
        out.bound(siege.accepted < wire, "host writes are not held to the wire rate")
        siege.bound(out)
    finally:
        daemon.stop()
    out.bound(daemon.proc.returncode == 0, "daemon did not exit 0")
    return out


def _network_flood(urls: list[str], seconds: float, seed: int, counter: Any) -> None:
    """Child process: connect to every `tcp://` or `rfc2217://` port and write random bytes at full
    speed, never reading (telnet's IAC escaped on RFC 2217, so every byte is data)."""
    chunk = random.Random(seed).randbytes(4096)
    socks: dict[socket.socket, bytes] = {}
    for url in urls:
        host, port = url.split("://", 1)[1].rsplit(":", 1)
        sock = socket.create_connection((host, int(port)))
        sock.setblocking(False)
        socks[sock] = chunk.replace(b"\xff", b"\xff\xff") if url.startswith("rfc2217") else chunk
    end = time.monotonic() + seconds
    written = 0
    while (left := end - time.monotonic()) > 0:
        _, ready, _ = select.select([], list(socks), [], left)
        for sock in ready:
            try:
                written += sock.send(socks[sock])
            except (BlockingIOError, ConnectionError):
                continue
    counter.value = written
    for sock in socks:
        sock.close()


def network_flood(workdir: Path, seconds: float = 60.0, idle_trips: int = 300) -> Outcome:
    """Random bytes at full speed into a TCP and an RFC 2217 port (an MS2000 and an MP-285 at 9600
    baud, realistic timing) by a client that never reads, while a host does `W X` round trips on a
    PTY port of the same daemon; afterwards each network port serves a new client."""
    out = Outcome("network flood: a TCP and an RFC 2217 client writing at full speed, never reading")
    network = [("tcp0", "ms2000", "tcp"), ("rfc0", "mp285", "rfc2217")]
    rig = {
        "spec": 1,
        "devices": [{"name": MEASURED, "profile": "ms2000", "ports": [{"timing": "realistic"}]}]
        + [
            {
                "name": name,
                "profile": profile,
                "ports": [{"transport": kind, "port": 0, "timing": "realistic"}],
            }
            for name, profile, kind in network
        ],
    }
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "rig.yaml").write_text(json.dumps(rig))
    daemon = start_daemon(workdir, [str(workdir / "rig.yaml")], expect_ports=1 + len(network))
    try:
        urls = [daemon.port(name) for name, _, _ in network]
        siege = _siege(daemon, _network_flood, urls, seconds, idle_trips)
        answers = [
            _answer_after_flood(url, profile) for url, (_, profile, _) in zip(urls, network, strict=True)
        ]
        out.figures.update(seconds=seconds, **siege.figures())
        # the wires' 960 characters/s, plus what socket buffers absorb (a few MiB a connection)
        wire = len(network) * (seconds * 960 + (16 << 20))
        out.bound(siege.accepted < wire, "writes not held to the wire rate")
        siege.bound(out)
        out.bound(all(answers), "a network port did not serve a new client after the flood")
    finally:
        daemon.stop()
    out.bound(daemon.proc.returncode == 0, "daemon did not exit 0")
    return out


def _answer_after_flood(url: str, profile: str) -> bool:
    """A new client on the port gets a well-formed answer: after the random bytes the device may be
    mid-frame or mid-line, so a terminator goes first, then a query whose reply shape is known."""
    request, length, ending = (b"c\r", 13, b"\r") if profile == "mp285" else (b"W X\r", None, b"\r\n")
    # a short timeout: the terminator's answer (if any) is a few characters, and a read that does not
    # fill waits out its timeout; the query's reply then gets as many reads as it needs
    with serial.serial_for_url(url, 9600, timeout=0.25) as port:
        for _ in range(5):
            port.write(b"\r")
            port.read(64)  # whatever the terminator set off
            port.write(request)
            got = b""
            for _ in range(8):
                got += port.read(length - len(got)) if length else port.read_until(ending)
                if got.endswith(ending):
                    break
            if got.endswith(ending) and (length is None or len(got) == length):
                return True
    return False


def open_close(workdir: Path, cycles: int = 10_000) -> Outcome:
    """Open and close every port `cycles` times, as a host program restarting over and over."""
    out = Outcome("open/close cycles per port")
    devices = [("mp", "mp285"), ("ms", "ms2000")]
    daemon = _start(workdir, devices, "fast")
    try:
        pid = daemon.proc.pid
        client = daemon.control()
        for name, _ in devices:  # warm up: first attach allocates what every later one reuses
            with serial.Serial(daemon.port(name), 9600, timeout=2):
                pass
            settle(client, name)
        fds, rss = fd_count(pid), rss_mb(pid)
        for _ in range(cycles):
            for name, _ in devices:
                with serial.Serial(daemon.port(name), 9600, timeout=2):
                    pass
        for name, _ in devices:
            settle(client, name)
        with serial.Serial(daemon.port("ms"), 9600, timeout=2) as port:
            round_trips(port, *W_X, count=3)
        settle(client, "ms")
        out.figures.update(
            cycles_per_port=cycles,
            fds_before=fds,
            fds_after=fd_count(pid),
            rss_before_mb=rss,
            rss_after_mb=rss_mb(pid),
            cpu_after_percent=cpu_percent(pid, 2.0),
        )
        out.bound(out.figures["fds_after"] == fds, "descriptors leaked")
        out.bound(out.figures["rss_after_mb"] - rss < 2.0, "RSS grew by >= 2 MB")
        out.bound(out.figures["cpu_after_percent"] < IDLE_CPU_PERCENT, "CPU used after the cycles")
    finally:
        daemon.stop()
    return out


def _mover(path: str, seconds: float, counter: Any) -> None:
    """Child process: make an MP-285 move back and forth as fast as it answers (two events a move)."""
    moves = 0
    end = time.monotonic() + seconds
    with serial.Serial(path, 9600, timeout=5) as port:
        while time.monotonic() < end:
            port.write(b"m" + struct.pack("<3i", 200 * (moves % 2), 0, 0) + b"\r")
            if port.read(1) != b"\r":
                raise AssertionError("move not acknowledged")
            moves += 1
    counter.value = moves


def slow_subscriber(workdir: Path, seconds: float = 60.0, devices: int = 3) -> Outcome:
    """A control client subscribes to `devices` MP-285s and never reads while hosts make them move
    as fast as they answer, at the highest time scale."""
    out = Outcome("control subscriber that never reads")
    names = [f"mp{i}" for i in range(devices)]
    daemon = _start(workdir, [(n, "mp285") for n in names], "fast", "--time-scale", "10000")
    try:
        pid = daemon.proc.pid
        silent = daemon.control()
        for name in names:
            silent.subscribe(name)  # and never reads again
        before = rss_mb(pid)
        counters = [multiprocessing.Value("q", 0) for _ in names]
        hosts = [
            multiprocessing.Process(target=_mover, args=(daemon.port(n), seconds, c))
            for n, c in zip(names, counters, strict=True)
        ]
        for host in hosts:
            host.start()
        for host in hosts:
            host.join()
        after = rss_mb(pid)
        listing = daemon.control().list()
        out.figures.update(
            seconds=seconds,
            events_published=2 * sum(c.value for c in counters),
            rss_before_mb=before,
            rss_after_mb=after,
        )
        out.bound(after - before < RSS_GROWTH_MB, f"RSS grew by >= {RSS_GROWTH_MB} MB")
        out.bound([d["device"] for d in listing] == names, "control channel stopped answering")
    finally:
        daemon.stop()
    return out


def stop_signals(workdir: Path) -> Outcome:
    """Every terminating signal, sent while a control client is subscribed, gives a clean exit 0:
    links and socket removed, no traceback logged."""
    out = Outcome("terminating signals")
    for sig in (signal.SIGHUP, signal.SIGINT, signal.SIGTERM, signal.SIGQUIT):
        daemon = _start(workdir / sig.name, [("ms", "ms2000")], "fast")
        link = Path(daemon.port("ms"))
        # not `daemon.control()`: `stop` closes those first, and this one must still be there
        subscriber: ControlClient | None = None
        try:
            subscriber = ControlClient(daemon.control_path)
            subscriber.subscribe("ms")
        finally:
            code = daemon.stop(sig)
            if subscriber is not None:
                subscriber.close()
        traceback = "Traceback" in daemon.stderr()
        clean = code == 0 and not os.path.lexists(link) and not daemon.control_path.exists()
        out.figures[sig.name] = "traceback" if traceback else "clean" if clean else f"exit {code}"
        out.bound(clean, f"{sig.name} did not shut down cleanly")
        out.bound(not traceback, f"{sig.name} with a subscriber connected logged a traceback")
    return out
