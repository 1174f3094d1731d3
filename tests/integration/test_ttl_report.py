"""TTL REPORT served by a daemon (MS-TTLREP-1, MS-5): the auxiliary port is created next to the main
one, announced in the ready output and `ctl list`, and carries a 16-byte frame per IN0 pulse; a host
that opens it and never reads blocks neither the main port nor the daemon."""

from __future__ import annotations

import os
import termios
from collections.abc import Iterator
from typing import Any

import pytest

from emulator.control_client import ControlClient
from protocols.clients import MS2000, TtlReportPort
from tests.support.daemon import RunningDaemon, start_daemon

DEVICE = "ms2000-ttlrep"
BAUD = 115200
#: more frames than the kernel (~18 KiB) and the transport (OUTPUT_LIMIT, 4 KiB) hold for a host
#: that never reads
FLOOD_FRAMES = 1800
#: generous: only a hang takes this long on any machine
HANG_S = 10.0


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    running = start_daemon(tmp_path_factory.mktemp("ttlrep"), ["--profile", DEVICE], expect_ports=2)
    yield running
    assert running.stop() == 0, running.stderr()


@pytest.fixture
def daemon(served: RunningDaemon) -> RunningDaemon:
    """The module's daemon with a factory-fresh device and the clock at scale 1."""
    with ControlClient(served.control_path) as ctl:
        ctl.reset(DEVICE)
        ctl.clock(1.0)
    return served


def test_ports_are_announced(daemon: RunningDaemon) -> None:
    main, aux = daemon.ports
    assert (main["port"], aux["port"]) == ("main", "aux")
    assert aux["path"] == main["path"] + ".aux"
    assert os.path.realpath(aux["path"]) == aux["pts"]
    listed = daemon.control().list()[0]["ports"]
    assert [(p["port"], p["path"]) for p in listed] == [("main", main["path"]), ("aux", aux["path"])]
    assert daemon.control().get(DEVICE, "ports") == {"main": main["path"], "aux": aux["path"]}


def test_a_pulse_sends_one_frame_on_the_aux_port(daemon: RunningDaemon) -> None:
    """Done means: `ttl_in0 pulse_ms=1` sends one 16-byte frame on the auxiliary port."""
    ctl = daemon.control()
    with (
        MS2000(daemon.port(DEVICE), BAUD, timeout=HANG_S) as stage,
        TtlReportPort(daemon.port(DEVICE, "aux"), BAUD, timeout=HANG_S) as frames,
    ):
        stage.move(X=1000, Y=-505)
        stage.wait_until_idle()
        assert stage.command("TTL X=6").ack
        ctl.input(DEVICE, "ttl_in0", pulse_ms=1)
        assert frames.read().by_axis() == {"X": 4540, "Y": -2292, "Z": 0}
        frames.port.timeout = 0.2
        assert frames.port.read(1) == b""
        assert stage.port.in_waiting == 0


def never_reading_host(path: str) -> int:
    """Opens the port at the device's baud and never reads it."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = termios.B115200
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return fd


def test_aux_host_that_never_reads_blocks_nothing(daemon: RunningDaemon) -> None:
    """Frames that do not fit are dropped and counted on the aux port; the main port keeps answering."""
    ctl = daemon.control()
    fd = never_reading_host(daemon.port(DEVICE, "aux"))
    try:
        with MS2000(daemon.port(DEVICE), BAUD, timeout=HANG_S) as stage:
            assert stage.command("TTL X=6").ack
            ctl.clock(100.0)  # frames leave 100 times faster: the flood takes seconds, not minutes
            for _ in range(FLOOD_FRAMES):
                ctl.input(DEVICE, "ttl_in0", pulse_ms=0.1)
            ctl.clock(1.0)
            with ControlClient(daemon.control_path) as watcher:
                watcher.subscribe(DEVICE, traffic=True)
                assert stage.version() == "USB-9.2k"  # answered, not stuck behind the aux port
                request, reply = main_port_records(watcher, 2)
        # and at once: the reply's last byte left its own wire time after the request (device
        # instants, unaffected by the host's load), nothing queued before it
        reply_wire = len(bytes.fromhex(reply["hex"])) * 10 / BAUD
        assert (request["dir"], reply["dir"]) == ("rx", "tx")
        assert reply["t"] - request["t"] == pytest.approx(reply_wire, abs=2e-6)
        report = ctl.get(DEVICE, "ttl_report")
        assert report["frames"] + report["overruns"] == FLOOD_FRAMES
        main, aux = (p["stats"] for p in ctl.list()[0]["ports"])
        assert main["output_dropped"] == 0
        assert 0 < aux["output_dropped"] <= report["frames"] * 16
        assert daemon.log.wait_line(f"{DEVICE}/aux: host is not reading", 0, HANG_S) is not None
    finally:
        os.close(fd)


def main_port_records(watcher: ControlClient, count: int) -> list[dict[str, Any]]:
    """The next `count` traffic records of the main port (the aux port's frames are left aside)."""
    records = []
    for record in watcher.events(timeout=HANG_S):
        if record["port"] == "main":
            records.append(record)
            if len(records) == count:
                break
    assert len(records) == count, records
    return records
