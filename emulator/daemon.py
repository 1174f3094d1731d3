"""The daemon: one asyncio loop hosting every device of a rig on its ports, plus the control channel.

No polling anywhere: transports wake the loop on host activity, each device runner arms one timer
for its next due event, and the control server waits on its socket. Readiness is one JSON line per
port on stdout (and optionally a ready file); SIGINT/SIGTERM remove links and socket and exit 0.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from emulator import registry
from emulator.clock import ScaledClock
from emulator.control import ControlServer
from emulator.device import Device, HostServices
from emulator.line import REALISTIC
from emulator.rig import DeviceSpec, Rig
from emulator.runner import DeviceRunner
from emulator.trafficlog import TrafficLog
from emulator.transports.pty import PtyTransport, runtime_dir

log = logging.getLogger("stage_emu.daemon")


@dataclass(frozen=True)
class DaemonOptions:
    timing: str | None = None  # overrides every port
    time_scale: float = 1.0
    ready_file: Path | None = None
    traffic_file: Path | None = None
    state_dir: Path | None = None
    control_path: Path | None = None
    link_dir: Path | None = None


def default_state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME")
    return (Path(base) if base else Path.home() / ".local" / "state") / "stage-emu"


class Daemon:
    def __init__(self, rig: Rig, options: DaemonOptions, out: TextIO = sys.stdout) -> None:
        self.rig = rig
        self.options = options
        self.out = out
        self.clock = ScaledClock(options.time_scale)
        self.runners: dict[str, DeviceRunner] = {}
        self.control: ControlServer | None = None
        self._traffic: TrafficLog | None = None
        self._stop = asyncio.Event()

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self._stop.set)
        try:
            await self.start()
            await self._stop.wait()
        finally:
            await self.shutdown()
        return 0

    def stop(self) -> None:
        self._stop.set()

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        links = self.options.link_dir or runtime_dir()
        if self.options.traffic_file is not None:
            self._traffic = TrafficLog(self.options.traffic_file.open("a", encoding="utf-8"))
        state_dir = self.options.state_dir or default_state_dir()
        services = HostServices(state_dir=state_dir)
        self.control = ControlServer(
            self.options.control_path or runtime_dir() / "control.sock", self.runners, self.clock
        )
        ready: list[dict[str, Any]] = []
        for spec in self.rig.devices:
            runner = DeviceRunner(
                _factory(spec, services),
                self.clock,
                loop=loop,
                traffic=self._traffic,
                on_event=self._publish,
            )
            self.runners[spec.name] = runner
            for port in spec.ports:
                default = spec.name if port.channel == "main" else f"{spec.name}.{port.channel}"
                link = port.link or links / default
                transport = PtyTransport(link, port.mode, loop)
                timing = self.options.timing or port.timing or REALISTIC
                runner.attach_transport(port.channel, transport, timing)
                line = {
                    "device": spec.name,
                    "profile": spec.profile.name,
                    "port": port.channel,
                    "path": transport.path,
                    "pts": transport.device_path,
                }
                ready.append(line)
            log.info("%s: %s (%s) ready", spec.name, spec.profile.name, spec.profile.description)
        await self.control.start()
        # Announced only once everything, control socket included, is up: these are the signal.
        if self.options.ready_file is not None:
            _write_atomic(
                self.options.ready_file,
                json.dumps({"ports": ready, "control": str(self.control.path), "pid": os.getpid()}),
            )
        for line in ready:
            self.out.write(json.dumps(line) + "\n")
        self.out.flush()

    def _publish(self, device: str, event: dict[str, Any]) -> None:
        if self.control is not None:
            self.control.publish(device, event)

    async def shutdown(self) -> None:
        for runner in self.runners.values():
            runner.close()
        if self.control is not None:
            await self.control.stop()
        if self._traffic is not None:
            self._traffic.close()
        if self.options.ready_file is not None:
            self.options.ready_file.unlink(missing_ok=True)


def _factory(spec: DeviceSpec, services: HostServices) -> Any:
    family = registry.family(spec.profile.family)
    assert family is not None  # the profile loader checked it

    def make(now: float) -> Device:
        return family.factory(spec.name, spec.profile, now, services)

    return make


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8") as handle:
        handle.write(text + "\n")
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)
