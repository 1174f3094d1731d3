"""`stage-emu serve --serial DEVICE` (and `transport: serial` in a rig) in a daemon, on a null-modem
cable of two pseudo-terminals (tests/support/nullmodem.py) standing in for a USB adapter and its
cable: replies byte-exact, the device's settings followed, a host at another baud rate garbled by
the "UARTs" themselves, an unplugged adapter (one line when it goes, one when it is back, the other
devices of the daemon answering meanwhile), each bad port one line at start, and the conformance
smoke sample over the serial port (a background run, tests/integration/conftest.py)."""

from __future__ import annotations

import json
import os
import re
import struct
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
import serial

from emulator.uart import Framing, garble
from tests.conformance.conftest import NO_MODEM, NO_PARITY
from tests.integration.conftest import SERIAL
from tests.support.daemon import ROOT, RunningDaemon, start_daemon
from tests.support.nullmodem import NullModem

if TYPE_CHECKING:
    from tests.integration.conftest import SmokeRuns

CLI = [sys.executable, "-m", "emulator.cli"]
TIMEOUT = 5.0
VERSION = b":A Version: USB-9.2k \r\n"
#: what a 19200-baud host sends so that a 9600 8N1 UART reads one clean CR (checked below)
CR_AT_19200 = bytes.fromhex("44 00")


@pytest.fixture
def cable(tmp_path: Path) -> Iterator[NullModem]:
    with NullModem(tmp_path / "cable") as made:
        yield made


def env(tmp_path: Path) -> dict[str, str]:
    run = tmp_path / "run"
    run.mkdir(exist_ok=True, mode=0o700)
    return {**os.environ, "PYTHONPATH": str(ROOT), "XDG_RUNTIME_DIR": str(run)}


def serve(tmp_path: Path, cable: NullModem, profile: str, *extra: str) -> RunningDaemon:
    args = ["--profile", profile, "--serial", str(cable.device_link), "--no-state", *extra]
    return start_daemon(tmp_path / "daemon", args, expect_ports=1, env=env(tmp_path))


def host_port(cable: NullModem, baud: int = 9600) -> serial.Serial:
    return serial.Serial(str(cable.host_link), baud, timeout=TIMEOUT)


def test_an_mp285_answers_byte_exact(tmp_path: Path, cable: NullModem) -> None:
    """Position frames carry FF bytes (negative coordinates), which the port's line-error marking
    doubles in the kernel: they come back exactly as sent (MP-11, MP-13)."""
    daemon = serve(tmp_path, cable, "mp285")
    try:
        assert daemon.ports == [
            {
                "device": "mp285",
                "profile": "mp285",
                "port": "main",
                "path": str(cable.device_link),
                "pts": os.path.realpath(cable.device_link),
                "transport": "serial",
            }
        ]
        with host_port(cable) as host:
            host.write(b"c\r")
            assert host.read(13) == bytes(12) + b"\r"
            target = struct.pack("<3i", -25, -1, 255)  # FF bytes in every coordinate
            host.write(b"m" + target + b"\r")
            assert host.read(1) == b"\r"  # the move is done (MP-13)
            host.write(b"c\r")
            assert host.read(13) == target + b"\r"
        listed = daemon.control().list()[0]["ports"][0]
        assert (listed["transport"], listed["path"], listed["attached"]) == (
            "serial",
            str(cable.device_link),
            True,
        )
        assert listed["host"] == (
            "host settings not visible on a serial line: a host at other settings gets garbage from the UART"
        )
    finally:
        assert daemon.stop() == 0


def test_an_ms2000_answers_and_its_port_follows_sb(tmp_path: Path, cable: NullModem) -> None:
    """MS-3: `SB X=2` puts the controller's UART at 2 stop bits at once, and the port with it; a host
    still at 1 stop bit is understood (a receiver checks the first stop bit only, MS-4)."""
    daemon = serve(tmp_path, cable, "ms2000", "--timing", "fast")
    try:
        with host_port(cable) as host:
            host.write(b"V\r")
            assert host.read_until(b"\r\n") == VERSION
            host.write(b"SB X=2\r")
            assert host.read_until(b"\r\n") == b":A\r\n"
            assert cable.device_settings().stop_bits == 2
            host.write(b"V\r")
            assert host.read_until(b"\r\n") == VERSION
            host.write(b"SB X=1\r")
            assert host.read_until(b"\r\n") == b":A\r\n"
            assert cable.device_settings().stop_bits == 1
    finally:
        assert daemon.stop() == 0


def test_a_host_at_another_baud_gets_garbage(tmp_path: Path, cable: NullModem) -> None:
    """The emulator cannot see a serial host's settings: the line garbles by itself. A 19200-baud
    host's `44 00` reaches the 9600-baud MS2000 as a lone CR, answered `:N-1` (MS-8), which the host
    reads as junk; at the right baud the same port answers cleanly."""
    assert [(c.value, c.framing_error) for c in garble(CR_AT_19200, Framing(19200), Framing(9600))] == [
        (0x0D, False)
    ]
    daemon = serve(tmp_path, cable, "ms2000")
    try:
        with host_port(cable, 19200) as host:
            host.write(CR_AT_19200)
            first = host.read(1)
            host.timeout = 0.3  # the rest of the junk, then silence
            junk = first + host.read(64)
        assert junk and b"\r\n" not in junk and junk != b":N-1\r\n"
        with host_port(cable) as host:
            host.write(b"V\r")
            assert host.read_until(b"\r\n") == VERSION
    finally:
        assert daemon.stop() == 0


def test_an_unplugged_adapter_comes_back_and_the_other_devices_answer_meanwhile(
    tmp_path: Path, cable: NullModem
) -> None:
    rig = tmp_path / "rig.yaml"
    stage = {"channel": "main", "transport": "serial", "device": str(cable.device_link), "timing": "fast"}
    devices = [
        {"name": "stage", "profile": "ms2000", "ports": [stage]},
        {"name": "pipette", "profile": "mp285", "ports": [{"channel": "main", "timing": "fast"}]},
    ]
    rig.write_text(json.dumps({"spec": 1, "devices": devices}))
    daemon = start_daemon(tmp_path / "daemon", [str(rig), "--no-state"], expect_ports=2, env=env(tmp_path))
    control = daemon.control()
    try:
        with (
            host_port(cable) as host,
            serial.Serial(daemon.port("pipette"), 9600, timeout=TIMEOUT) as pipette,
        ):
            host.write(b"V\r")
            assert host.read_until(b"\r\n") == VERSION
            cable.unplug()
            assert daemon.log.wait_line("serial port gone", 0, TIMEOUT) is not None
            assert control.list()[0]["ports"][0]["attached"] is False
            for _ in range(3):  # the pipette's port is served as before
                pipette.write(b"c\r")
                assert pipette.read(13) == bytes(12) + b"\r"
            cable.replug()
            assert daemon.log.wait_line("serial port is back", 0, TIMEOUT) is not None
            host.write(b"V\r")
            assert host.read_until(b"\r\n") == VERSION
        log = daemon.stderr()
        assert log.count("serial port gone") == 1 and log.count("serial port is back") == 1, log
        assert f"{cable.device_link}: serial port gone (hang-up); trying to reopen it every 0.5 s" in log
    finally:
        assert daemon.stop() == 0


# ---- bad input: one line at start ----------------------------------------------------------------


def refused(tmp_path: Path, *args: str) -> str:
    """`stage-emu serve ARGS`: exit status 1 and one line on stderr, returned."""
    result = subprocess.run(
        [*CLI, "serve", "--no-state", *args],
        cwd=ROOT,
        env=env(tmp_path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1, result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr, result.stderr
    return result.stderr.removeprefix("stage-emu: ").rstrip("\n")


def test_a_missing_device_is_one_line(tmp_path: Path) -> None:
    missing = tmp_path / "ttyUSB7"
    assert refused(tmp_path, "--profile", "ms2000", "--serial", str(missing)) == (
        f"serial port {missing}: no such device "
        "(is the adapter plugged in? `ls /dev/serial/by-id` lists them)"
    )


def test_a_busy_device_is_one_line(tmp_path: Path, cable: NullModem) -> None:
    with serial.Serial(str(cable.device_link), exclusive=True):
        assert refused(tmp_path, "--profile", "ms2000", "--serial", str(cable.device_link)) == (
            f"serial port {cable.device_link}: in use by another program (it is opened exclusively)"
        )


def test_what_is_not_a_serial_port_is_one_line(tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me\n")
    assert refused(tmp_path, "--profile", "mp285", "--serial", str(notes)) == (
        f"serial port {notes}: not a serial port (it is a regular file)"
    )
    assert notes.read_text() == "keep me\n"
    assert refused(tmp_path, "--profile", "mp285", "--serial", "/dev/null") == (
        "serial port /dev/null: not a serial port (the system refuses terminal settings on it)"
    )


def test_settings_the_port_cannot_take_are_one_line(tmp_path: Path, cable: NullModem) -> None:
    """An MP-285 set to even parity (MP-1) on a port that keeps no parity (a pseudo-terminal)."""
    profile = tmp_path / "even.yaml"
    profile.write_text(json.dumps({"spec": 1, "extends": "mp285", "line": {"parity": "even"}}))
    assert refused(tmp_path, "--profile", str(profile), "--serial", str(cable.device_link)) == (
        f"serial port {cable.device_link}: does not support even parity (it keeps none)"
    )


def test_serial_options_and_rig_entries_are_checked_in_one_line(tmp_path: Path) -> None:
    assert refused(tmp_path, "--profile", "ms2000", "--serial", "/dev/x", "--tcp", "7000") == (
        "give --tcp or --serial, not both (a rig file can serve several ports)"
    )
    assert refused(tmp_path, "--serial", "/dev/x") == (
        "--serial goes with --profile (in a rig file, give the port `transport: serial`)"
    )
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "spec: 1\ndevices:\n  - {name: a, profile: ms2000, ports: [{transport: serial, link: x}]}\n"
    )
    result = subprocess.run(
        [*CLI, "validate", str(rig)], cwd=ROOT, env=env(tmp_path), capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 1
    assert result.stderr.splitlines() == [
        f"{rig}:3: devices[0].ports[0].device: a serial port needs the device to open "
        "(/dev/ttyUSB0, COM7, a pyserial URL)"
    ]


# ---- the conformance smoke sample over a serial port ---------------------------------------------

#: what a skip over the null-modem cable may say: parity or modem lines (pseudo-terminals carry
#: neither), or a vector that needs the host's settings seen, or a line error marked
#: (tests/conformance/conftest.py SERIAL_LIMITS)
SERIAL_SKIPS = re.compile(f"{re.escape(NO_PARITY)}|{re.escape(NO_MODEM)}|needs .+: not on a serial line .+")


@pytest.mark.parametrize("transport", [SERIAL])
@pytest.mark.parametrize("family", ["mp285", "ms2000"])
def test_conformance_smoke_runs_over_a_serial_port(
    smoke_runs: SmokeRuns, family: str, transport: str
) -> None:
    run = smoke_runs.runs.get((family, transport))
    assert run is not None, smoke_runs.failed[family, transport]
    assert run.wait() == 0, run.report()
    passed = 0
    for case in ElementTree.parse(run.junit).iter("testcase"):
        skipped = case.find("skipped")
        if skipped is None:
            passed += 1
        else:
            assert SERIAL_SKIPS.fullmatch(skipped.get("message", "")), (
                case.get("name"),
                skipped.get("message"),
            )
    assert passed >= 5, run.report()
