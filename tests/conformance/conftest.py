"""Conformance targets: the emulator (default) or a real controller (`--port PATH --device FAMILY`).

Tests open the port with pyserial exactly as a host program would. `open_target(profile, overrides)`
returns a `Target`; on the emulator each call gets a factory-fresh device (same daemon reused per
profile/overrides/timing), on a real port the profile only supplies line settings and tests that ask
for non-default profiles or overrides are skipped (mark tests that need the control channel
`@pytest.mark.control`, exact timing `@pytest.mark.timing`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import serial

from emulator.control import ControlClient
from emulator.profile import Profile, load_profile
from tests.support.daemon import RunningDaemon, start_daemon


@dataclass
class Target:
    """What a conformance test talks to."""

    path: str
    family: str
    profile: Profile
    real: bool
    device: str | None = None
    control: ControlClient | None = None
    baud: int | None = None
    _ports: list[serial.Serial] = field(default_factory=list)

    def open(self, **overrides: Any) -> serial.Serial:
        """The port opened with the profile's line settings, as a host program would."""
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
        port = serial.Serial(self.path, **settings)
        self._ports.append(port)
        return port

    def ctl(self) -> ControlClient:
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
        if self.control is not None:
            self.control.close()  # the daemon serves a bounded number of control connections


class DaemonPool:
    """One emulator daemon per (profile, overrides, timing), started on first use."""

    def __init__(self, workdir: Path) -> None:
        self._workdir = workdir
        self._daemons: dict[str, RunningDaemon] = {}

    def get(
        self, profile: str, overrides: dict[str, Any] | None, timing: str, dedicated: bool
    ) -> RunningDaemon:
        key = json.dumps([profile, overrides, timing], sort_keys=True)
        if dedicated or key not in self._daemons:
            workdir = self._workdir / f"d{len(self._daemons)}-{'x' if dedicated else ''}{abs(hash(key))}"
            workdir.mkdir(parents=True, exist_ok=True)
            rig = workdir / "rig.yaml"
            rig.write_text(
                json.dumps(
                    {
                        "spec": 1,
                        "devices": [
                            {
                                "name": "dut",
                                "profile": profile,
                                "overrides": overrides,
                                "ports": [{"timing": timing}],
                            }
                        ],
                    }
                )
            )
            daemon = start_daemon(workdir, [str(rig)], expect_ports=1)
            if dedicated:
                return daemon
            self._daemons[key] = daemon
        return self._daemons[key]

    def stop(self) -> None:
        for daemon in self._daemons.values():
            daemon.stop()


@pytest.fixture(scope="session")
def daemon_pool(tmp_path_factory: pytest.TempPathFactory) -> Iterator[DaemonPool]:
    pool = DaemonPool(tmp_path_factory.mktemp("conformance"))
    yield pool
    pool.stop()


@pytest.fixture
def open_target(request: pytest.FixtureRequest, daemon_pool: DaemonPool) -> Iterator[Callable[..., Target]]:
    """`open_target(profile, overrides=None, timing="realistic", dedicated=False) -> Target`."""
    real_port = request.config.getoption("--port")
    opened: list[Target] = []
    dedicated_daemons: list[RunningDaemon] = []

    def factory(
        profile: str,
        overrides: dict[str, Any] | None = None,
        timing: str = "realistic",
        dedicated: bool = False,
    ) -> Target:
        loaded = load_profile(profile, overrides=overrides)
        if real_port:
            family = request.config.getoption("--device")
            if loaded.family != family:
                pytest.skip(f"test for {loaded.family}, port has {family}")
            if overrides or dedicated or profile != family:
                pytest.skip(f"needs emulator profile {profile} {overrides or ''}")
            target = Target(real_port, family, loaded, True, baud=request.config.getoption("--baud"))
        else:
            daemon = daemon_pool.get(profile, overrides, timing, dedicated)
            if dedicated:
                dedicated_daemons.append(daemon)
            control = daemon.control()
            control.request({"op": "clock", "scale": 1.0})
            control.resume()
            control.fault("dut", "clear")
            control.reset("dut")
            target = Target(daemon.port("dut"), loaded.family, loaded, False, "dut", control)
        opened.append(target)
        return target

    yield factory
    for target in opened:
        target.close()
    for daemon in dedicated_daemons:
        daemon.stop()
