"""Conformance targets: the emulator (default) or a real controller (`--port PATH --device FAMILY`).

Tests open the port with pyserial exactly as a host program would. `open_target(profile, overrides)`
returns a `Target`; on the emulator each call gets a factory-fresh device: by default one served in
this process in virtual time (device time passes at once whenever the host waits, so every instant
is exact and no test waits for the wall clock), with `--target daemon` one of a daemon's
pseudo-terminals in real time (same daemon reused per profile/overrides/timing), with `--target
serial` a daemon's serial port (`transport: serial`) on one end of a null-modem cable of two
pseudo-terminals (tests/support/nullmodem.py), the test opening the other end. A test's clock is
`Target.monotonic()`: the device's in virtual time, the wall clock's otherwise. On a real port the
profile only supplies line settings and tests that ask for non-default profiles or overrides are
skipped (mark tests that need the control channel `@pytest.mark.control`, exact timing
`@pytest.mark.timing`). A `stageemu://` URL as `--port` is an
emulator in the test process, which has every profile: those tests run on it, with the URL's profile
swapped. An `rfc2217://` URL opens with `Rfc2217Port`. A device's second port (the MS2000's TTL
REPORT `aux`) opens with `Target.open_aux()`: served next to the main port on the emulator,
`--aux-port PATH` on real hardware (skipped without it).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit

import pytest
import serial
from serial import rfc2217

import emulator.urlhandler  # noqa: F401  (registers stageemu:// URLs for --port)
from emulator.control_client import ControlClient, ControlRequests
from emulator.profiles.profile import Profile, load_profile
from emulator.profiles.registry import channels_of
from emulator.urlhandler.control import HostedControl
from emulator.urlhandler.hosted import HostedDevice, serve
from emulator.urlhandler.url import SCHEME, VIRTUAL, UrlOptions
from tests.support.daemon import RunningDaemon, start_daemon
from tests.support.nullmodem import NullModem


class Rfc2217Port(rfc2217.Serial):
    """pyserial's RFC 2217 client (what `serial_for_url("rfc2217://...")` opens) with two of its
    waits taken out of the host's timing; the data and the line settings it sends are the same.

    - A new read timeout stays in the client. pyserial renegotiates every line setting with the
      server on each timeout change (0.1 s or more, polled), which the vectors make before most
      reads: a read meant to end at an instant on the host's clock would end that much later.
    - Closing waits for the server to close its end (the reader thread sees EOF) instead of
      pyserial's fixed 0.3 s sleep "in case of quick reconnects": once it has, the server has let go
      of the port and the next test's connection is not refused as a second host.
    """

    @property
    def timeout(self) -> float | None:
        return self._timeout

    @timeout.setter
    def timeout(self, value: float | None) -> None:
        self._timeout = value

    def close(self) -> None:
        reader, sock = self._thread, self._socket
        if reader is not None and sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_WR)  # the server sees the hang-up ...
            reader.join(self._network_timeout)  # ... and closes its end: EOF ends the reader
            self._thread = None  # so pyserial's close neither joins it again nor sleeps
        super().close()


@dataclass
class Target:
    """What a conformance test talks to."""

    path: str
    family: str
    profile: Profile
    real: bool
    device: str | None = None
    control: ControlRequests | None = None
    baud: int | None = None
    #: the auxiliary port (None: the device has none, or `--aux-port` was not given)
    aux_path: str | None = None
    #: the device served in this process in virtual time (None: a daemon's or a real port)
    hosted: HostedDevice | None = None
    _ports: list[serial.SerialBase] = field(default_factory=list)

    @property
    def virtual(self) -> bool:
        return self.hosted is not None

    def monotonic(self) -> float:
        """The test's clock in seconds: the device's in virtual time (the host's waits move it),
        the wall clock's on a daemon or a real port."""
        return time.monotonic() if self.hosted is None else self.hosted.now()

    def open_aux(self, **overrides: Any) -> serial.SerialBase:
        """The auxiliary port, at the main port's settings (MS-5)."""
        if self.aux_path is None:
            pytest.skip("needs the auxiliary port (--aux-port on a real controller)")
        return self.open(path=self.aux_path, **overrides)

    def open(self, path: str | None = None, **overrides: Any) -> serial.SerialBase:
        """The port (default: the main one) opened with the profile's line settings, as a host
        program would."""
        line = self.profile.line
        settings: dict[str, Any] = {
            "baudrate": self.baud or line.baud,
            "bytesize": line.data_bits,
            "parity": {"none": serial.PARITY_NONE, "even": serial.PARITY_EVEN, "odd": serial.PARITY_ODD}[
                line.parity
            ],
            "stopbits": line.stop_bits,
            "rtscts": line.flow_control == "rtscts",
            "timeout": 2.0,
        }
        settings.update(overrides)
        url = path or self.path  # a device path, an rfc2217:// or a stageemu:// URL
        port = (
            Rfc2217Port(url, **settings)
            if url.startswith("rfc2217://")
            else serial.serial_for_url(url, **settings)
        )
        self._ports.append(port)
        return port

    def ctl(self) -> ControlRequests:
        if self.control is None:
            pytest.skip("needs the emulator's control channel")
        return self.control

    def input(self, input_name: str, /, **params: Any) -> Any:
        return self.ctl().input(self.device, input_name, **params)

    def get(self, name: str) -> Any:
        return self.ctl().get(self.device, name)

    def close(self) -> None:
        for port in self._ports:
            port.close()
        if isinstance(self.control, ControlClient):
            self.control.close()  # the daemon serves a bounded number of control connections
        if self.hosted is not None:
            self.hosted.close()


def carries_parity(config: pytest.Config) -> bool:
    """Whether the data bits and parity a host sets reach the device: not on the emulator's
    pseudo-terminals (`--target daemon`, or a PTY as `--port`: the pty driver clears PARENB, MP-4),
    nor through a raw TCP socket (no line settings at all); in virtual time (the device is served in
    process: a `stageemu://` port), on an RFC 2217 port and a real port they do."""
    port = config.getoption("--port")
    if not port:
        return bool(config.getoption("--target") == "virtual")
    if port.startswith("socket://"):
        return False
    return not os.path.realpath(port).startswith("/dev/pts/")


#: the skip where they do not
NO_PARITY = "needs a port that carries parity (an RFC 2217 transport, a stageemu:// URL or a real port)"

#: Vectors `--target serial` cannot carry, by test (name, or name with its parameters): a serial line
#: shows the emulator nothing of the host's settings (a host at other settings is garbled by the line
#: itself), and a cable of pseudo-terminals cannot mark a framing error to the emulator as a UART does
HOST_UNSEEN = (
    "needs the host's settings seen by the emulator: not on a serial line (the line garbles by itself)"
)
UNMARKED = "needs framing errors marked to the emulator: not on a serial line of ptys (a UART marks them)"
FROZEN_WIRE = (
    "steps device time by the control channel while its bytes are still on the line: a serial line "
    "carries them in wall time, so they cross at other device instants than the vector's"
)
SERIAL_LIMITS = {
    "test_tv_003_mismatch_is_logged_once": HOST_UNSEEN,
    "test_tv_003_line_mismatch_ignore_passes_bytes": HOST_UNSEEN,
    "test_tv_005_usb_without_rtscts_loses_bytes_while_busy": HOST_UNSEEN,
    "test_tv_117_dip_baud_read_at_power_up": HOST_UNSEEN,  # declares the host at the device's baud
    "test_tv_003_host_at_another_baud_gets_no_reply[4800-31]": UNMARKED,
    "test_tv_034_second_move_is_held": FROZEN_WIRE,
    "test_tv_037_lf_after_a_move[terminators_interrupt_move]": FROZEN_WIRE,
    "test_tv_167_focus_curve_states": FROZEN_WIRE,  # TV-166 sweeps the same curve in real time
}


def carries_modem_lines(config: pytest.Config) -> bool:
    """Whether the device's modem lines reach the host, and the host's RTS the device: in virtual
    time and over a `stageemu://` or `rfc2217://` port; not on a pseudo-terminal (`--target daemon`)
    or a raw TCP socket, which carry none, nor on a real port given as a device path, whose cable
    may not carry them (three wires, no null-modem wiring)."""
    port = config.getoption("--port")
    if not port:
        return bool(config.getoption("--target") == "virtual")
    return bool(port.startswith(("stageemu://", "rfc2217://")))


#: the skip of tests marked `modem` where they do not
NO_MODEM = "needs modem lines (an RFC 2217 port, a stageemu:// URL or the default in-process target)"


@pytest.fixture(autouse=True)
def _skip_without_modem_lines(request: pytest.FixtureRequest) -> None:
    if request.node.get_closest_marker("modem") and not carries_modem_lines(request.config):
        pytest.skip(NO_MODEM)


class DaemonPool:
    """One emulator daemon per (profile, overrides, timing), started on first use."""

    def __init__(self, workdir: Path) -> None:
        self._workdir = workdir
        self._daemons: dict[str, RunningDaemon] = {}

    def main_port(self, workdir: Path, timing: str) -> dict[str, Any]:
        """The rig entry of the device's main port."""
        return {"channel": "main", "timing": timing}

    def host_path(self, daemon: RunningDaemon) -> str:
        """What the host opens for the main port."""
        return daemon.port("dut")

    def get(self, profile: str, overrides: dict[str, Any] | None, timing: str) -> RunningDaemon:
        key = json.dumps([profile, overrides, timing], sort_keys=True)
        if key not in self._daemons:
            workdir = self._workdir / f"d{len(self._daemons)}-{abs(hash(key))}"
            workdir.mkdir(parents=True, exist_ok=True)
            rig = workdir / "rig.yaml"
            channels = channels_of(load_profile(profile, overrides=overrides))
            rig.write_text(
                json.dumps(
                    {
                        "spec": 1,
                        "devices": [
                            {
                                "name": "dut",
                                "profile": profile,
                                "overrides": overrides,
                                "ports": [
                                    self.main_port(workdir, timing)
                                    if c == "main"
                                    else {"channel": c, "timing": timing}
                                    for c in channels
                                ],
                            }
                        ],
                    }
                )
            )
            self._daemons[key] = start_daemon(workdir, [str(rig)], expect_ports=len(channels))
        return self._daemons[key]

    def stop(self) -> None:
        for daemon in self._daemons.values():
            daemon.stop()


class SerialPool(DaemonPool):
    """`--target serial`: each daemon serves its main port on one end of a null-modem cable (a
    bridge thread in this process); the host opens the other end."""

    def __init__(self, workdir: Path) -> None:
        super().__init__(workdir)
        self._cables: dict[Path, NullModem] = {}

    def main_port(self, workdir: Path, timing: str) -> dict[str, Any]:
        cable = self._cables[workdir] = NullModem(workdir / "cable").start()
        return {"channel": "main", "transport": "serial", "device": str(cable.device_link), "timing": timing}

    def host_path(self, daemon: RunningDaemon) -> str:
        return str(self._cables[daemon.workdir].host_link)

    def stop(self) -> None:
        super().stop()
        for cable in self._cables.values():
            cable.close()


@pytest.fixture(scope="session")
def daemon_pool(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[DaemonPool]:
    kind = SerialPool if request.config.getoption("--target") == "serial" else DaemonPool
    pool = kind(tmp_path_factory.mktemp("conformance"))
    yield pool
    pool.stop()


def profile_url(
    port: str, profile: str, overrides: dict[str, Any] | None, tmp_path_factory: pytest.TempPathFactory
) -> str | None:
    """A `stageemu://` port is an emulator in this process, so every profile is at hand: `port` with
    `profile` in place of its own (with `overrides`, a profile file extending it). None for any other
    port: it has the one controller it has."""
    parts = urlsplit(port)
    if parts.scheme != SCHEME:
        return None
    host, query = profile, [(key, value) for key, value in parse_qsl(parts.query) if key != "profile"]
    if overrides:
        host, query = "", [("profile", profile_file(profile, overrides, tmp_path_factory)), *query]
    return f"{SCHEME}://{host}" + (f"?{urlencode(query)}" if query else "")


def profile_file(profile: str, overrides: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> str:
    """A profile file extending `profile` with `overrides`, as a `stageemu://` URL or `serve` takes."""
    path = tmp_path_factory.mktemp("profile") / "profile.yaml"
    path.write_text(json.dumps({"spec": 1, "extends": profile, **overrides}))
    return str(path)


def virtual_target(
    profile: str, overrides: dict[str, Any] | None, timing: str, tmp_path_factory: pytest.TempPathFactory
) -> Target:
    """A factory-fresh device served in this process in virtual time, with its control channel."""
    loaded = load_profile(profile, overrides=overrides)
    source = profile_file(profile, overrides, tmp_path_factory) if overrides else profile
    hosted = serve(UrlOptions(profile=source, timing=timing, time=VIRTUAL))
    aux = hosted.url("aux") if "aux" in hosted.channels else None
    control = HostedControl(hosted, "dut")
    return Target(hosted.url(), loaded.family, loaded, False, "dut", control, aux_path=aux, hosted=hosted)


@pytest.fixture
def open_target(
    request: pytest.FixtureRequest, daemon_pool: DaemonPool, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Callable[..., Target]]:
    """`open_target(profile, overrides=None, timing="realistic") -> Target`."""
    real_port = request.config.getoption("--port")
    opened: list[Target] = []

    def factory(profile: str, overrides: dict[str, Any] | None = None, timing: str = "realistic") -> Target:
        loaded = load_profile(profile, overrides=overrides)
        if real_port:
            family = request.config.getoption("--device")
            if loaded.family != family:
                pytest.skip(f"test for {loaded.family}, port has {family}")
            path = real_port
            if overrides or profile != family:
                path = profile_url(real_port, profile, overrides, tmp_path_factory)
                if path is None:
                    pytest.skip(f"needs emulator profile {profile} {overrides or ''}")
            baud = request.config.getoption("--baud")
            aux = request.config.getoption("--aux-port")
            target = Target(path, family, loaded, True, baud=baud, aux_path=aux)
        elif request.config.getoption("--target") == "virtual":
            target = virtual_target(profile, overrides, timing, tmp_path_factory)
        else:
            if isinstance(daemon_pool, SerialPool):
                node = request.node
                limit = SERIAL_LIMITS.get(node.name) or SERIAL_LIMITS.get(getattr(node, "originalname", ""))
                if limit:
                    pytest.skip(limit)
            daemon = daemon_pool.get(profile, overrides, timing)
            control = daemon.control()
            control.request({"op": "clock", "scale": 1.0})
            control.resume()
            control.fault("dut", "clear")
            control.reset("dut")
            aux = next((p["path"] for p in daemon.ports if p["port"] == "aux"), None)
            path = daemon_pool.host_path(daemon)
            target = Target(path, loaded.family, loaded, False, "dut", control, aux_path=aux)
        opened.append(target)
        return target

    yield factory
    for target in opened:
        target.close()
