"""The daemon: one asyncio loop hosting every device of a rig on its ports, plus the control channel.

No polling anywhere: transports wake the loop on host activity, each device runner arms one timer
for its next due event, and the control server waits on its socket. Readiness is one JSON line per
port on stdout (and optionally a ready file).

Signals: SIGINT, SIGTERM, SIGHUP (the terminal that ran it closed) and SIGQUIT shut down cleanly
(links, socket and ready file removed, logs flushed, exit 0); SIGUSR1 reopens the traffic log (log
rotation); SIGUSR2 logs one status line per device. The daemon removes only what it created
(emulator/storage/runtime.py keeps the record).

Non-volatile memory has one owner at a time: a device store file another process holds (a daemon
on the same --state-dir) stops start-up with one line naming its pid, before any port exists.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import logging
import os
import resource
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from emulator.device import Device, DeviceServices, Store, StoreOpener, StoreReport
from emulator.hosting.clock import ScaledClock
from emulator.hosting.control import ControlServer
from emulator.hosting.lag import WorkBudget
from emulator.hosting.ratelimit import LOG_INTERVAL_S, LogLimiter, held_note
from emulator.hosting.rig import DeviceSpec, Rig
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import TrafficLog
from emulator.hosting.transports import create as create_transport
from emulator.profiles import registry
from emulator.storage.nvstore import FlashWriter, ReportingStore, StateInUse, StorageError
from emulator.storage.runtime import (
    LINK,
    READY,
    SOCKET,
    Ownership,
    SetupError,
    check_output_path,
    check_ready_file,
    private_dir,
    remove_ready_file,
    runtime_dir,
    write_private_atomic,
)
from emulator.wire_time import REALISTIC

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
#: the same loop error is logged at most once per this many seconds (e.g. out of descriptors)
ERROR_LOG_INTERVAL = LOG_INTERVAL_S

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
    #: devices keep their non-volatile memory in memory only: nothing read from or saved to disk
    no_state: bool = False


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
        self._ownership: Ownership | None = None
        self._ready_written: tuple[int, int] | None = None
        self._errors = _RateLimitedErrors()
        #: writes every device's non-volatile memory on its own thread (emulator/storage/nvstore.py)
        self._flash: FlashWriter | None = None
        #: the devices that opened each device_id's memory (two devices of a rig may share one)
        self._store_users: dict[str, list[str]] = {}
        self._closing = False

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        loop.set_exception_handler(self._errors.handle)
        for sig in STOP_SIGNALS:
            loop.add_signal_handler(sig, self._on_stop_signal, sig)
        loop.add_signal_handler(signal.SIGUSR1, self._reopen_logs)
        loop.add_signal_handler(signal.SIGUSR2, self._log_status)
        try:
            await self.start()
            # What start-up built lives as long as the daemon: kept out of the collector's full
            # passes, which otherwise traverse all of it and stall a round trip now and then.
            gc.freeze()
            await self._stop.wait()
        finally:
            await self.shutdown()
        return 0

    def stop(self) -> None:
        self._stop.set()

    def _on_stop_signal(self, sig: signal.Signals) -> None:
        log.info("%s: shutting down", signal.Signals(sig).name)
        self._stop.set()

    def _reopen_logs(self) -> None:
        if self._traffic is not None:
            self._traffic.reopen()

    def _log_status(self) -> None:
        for name, runner in self.runners.items():
            ports = ", ".join(
                f"{ch.name}: {'attached' if ch.attached else 'idle'}" for ch in runner.channels.values()
            )
            log.warning("%s (%s): %s", name, runner.device.profile.name, ports)

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        _raise_descriptor_limit()
        run_dir = runtime_dir()
        self._ownership = Ownership(run_dir)
        self._ownership.acquire()
        links = private_dir(self.options.link_dir, "--link-dir") if self.options.link_dir else run_dir
        ready_file = self.options.ready_file
        if ready_file is not None:
            ready_file = check_output_path(ready_file, "--ready-file")
            check_ready_file(ready_file)
        if self.options.traffic_file is not None:
            traffic = check_output_path(self.options.traffic_file, "--log-traffic")
            try:
                self._traffic = TrafficLog(traffic)
            except OSError as exc:
                raise SetupError(f"--log-traffic {traffic}: cannot open: {exc.strerror or exc}") from None
        if not self.options.no_state:
            state_dir = self.options.state_dir or default_state_dir()
            self._flash = FlashWriter(state_dir, loop.call_soon_threadsafe)
        # The models first: each claims its store file, so a refusal comes before any socket or port.
        for spec in self.rig.devices:
            self.runners[spec.name] = DeviceRunner(
                _factory(spec, DeviceServices(stores=self._stores_for(spec.name))),
                self.clock,
                loop=loop,
                traffic=self._traffic,
                on_event=self._publish,
                budget=WorkBudget(),  # one device behind the clock must not hold the loop (lag.py)
            )
        control_path = (
            check_output_path(self.options.control_path, "--control")
            if self.options.control_path
            else run_dir / "control.sock"
        )
        traffic_path = None if self._traffic is None else self._traffic.path
        self.control = ControlServer(control_path, self.runners, self.clock, traffic_path)
        self._ownership.record(SOCKET, control_path)
        await self.control.start()
        ready: list[dict[str, Any]] = []
        for spec in self.rig.devices:
            runner = self.runners[spec.name]
            for port in spec.ports:
                default = spec.name if port.channel == "main" else f"{spec.name}.{port.channel}"
                link = port.link or links / default
                if port.transport == "pty":
                    self._ownership.record(LINK, link)
                transport = create_transport(port, link, loop)
                timing = self.options.timing or port.timing or REALISTIC
                runner.attach_transport(port.channel, transport, timing)
                line = {
                    "device": spec.name,
                    "profile": spec.profile.name,
                    "port": port.channel,
                    "path": transport.path,
                    "pts": transport.device_path,
                    "transport": transport.kind,
                }
                ready.append(line)
            log.info("%s: %s (%s) ready", spec.name, spec.profile.name, spec.profile.description)
        # Announced only once everything, control socket included, is up: these are the signal.
        if ready_file is not None:
            self._ownership.record(READY, ready_file, pid=os.getpid())
            body = {"ports": ready, "control": str(self.control.path), "pid": os.getpid()}
            try:
                self._ready_written = write_private_atomic(ready_file, json.dumps(body) + "\n")
            except OSError as exc:
                raise SetupError(f"--ready-file {ready_file}: cannot write: {exc.strerror or exc}") from None
        for line in ready:
            self.out.write(json.dumps(line) + "\n")
        self.out.flush()

    def _stores_for(self, device: str) -> StoreOpener:
        """Stores of `device` write on the flash writer's thread, never on the loop. Their outcome
        comes back on the loop and goes to the model through its runner, between two model calls,
        so what it causes (the `storage_error` flag and event, a held `SS` reply) flows out at once."""

        def open_store(device_id: str, report: StoreReport) -> Store:
            def settled(failure: StorageError | None) -> None:
                runner = self.runners.get(device)
                if runner is None or self._closing:  # no ports to carry what it causes: the model alone
                    report(failure)
                else:
                    runner.call(lambda now: report(failure))

            if self._flash is None:  # --no-state: the flash lives and dies with the model
                return ReportingStore(None, device_id, report)
            users = self._store_users.setdefault(device_id, [])
            if device not in users:
                if users:
                    log.warning(
                        "%s and %s share one non-volatile memory (device_id %s): each one's saves "
                        "overwrite the other's; give each its own device_id in its profile or rig overrides",
                        users[0],
                        device,
                        device_id,
                    )
                users.append(device)
            try:
                return self._flash.open(device_id, settled)
            except StateInUse as exc:
                owner = "another stage-emu" if exc.pid is None else f"another stage-emu (pid {exc.pid})"
                raise SetupError(
                    f"{device}: non-volatile memory {exc.path} is in use by {owner}; give this daemon "
                    "its own --state-dir DIR, or --no-state to keep its devices' memory for this run only"
                ) from None

        return open_store

    def _publish(self, device: str, event: dict[str, Any]) -> None:
        if self.control is not None:
            self.control.publish(device, event)

    async def shutdown(self) -> None:
        """Undo what start did, each step on its own so one failure does not leave the rest behind."""
        self._closing = True
        self._errors.closing = True
        for runner in self.runners.values():
            _cleanup_step(f"closing {runner.name}", runner.close)
        if self._flash is not None:
            # the last image of every store reaches the disk before we exit (SIGTERM loses no save)
            await asyncio.to_thread(self._flash.close)
        if self.control is not None:
            await self.control.stop()
        if self._traffic is not None:
            self._traffic.close()
        if self.options.ready_file is not None:
            path = self.options.ready_file.expanduser().absolute()
            _cleanup_step("removing the ready file", lambda: remove_ready_file(path, self._ready_written))
        if self._ownership is not None:
            _cleanup_step("releasing the owner record", self._ownership.release)


def _factory(spec: DeviceSpec, services: DeviceServices) -> Any:
    family = registry.family(spec.profile.family)
    assert family is not None  # the profile loader checked it

    def make(now: float) -> Device:
        return family.factory(spec.name, spec.profile, now, services)

    return make


def _cleanup_step(what: str, action: Any) -> None:
    try:
        action()
    except OSError as exc:
        log.error("shutdown: %s failed: %s", what, exc)


def _raise_descriptor_limit() -> None:
    """Each port and control connection costs descriptors: use all the system grants us."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = hard if hard != resource.RLIM_INFINITY else max(soft, 65536)
    if soft < target:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))


@dataclass
class _RateLimitedErrors:
    """The loop's exception handler: one line per kind of error per ERROR_LOG_INTERVAL, with a count
    of the repeats it held back (emulator/hosting/ratelimit.py, the policy the network ports share).
    Resource exhaustion (out of descriptors, memory) floods otherwise: asyncio retries `accept` and
    logs a traceback each time."""

    clock: Any = time.monotonic
    #: the daemon is shutting down: what fails now is a callback of something already closed (asyncio
    #: retries `accept` after EMFILE on a timer, and that timer can fire on a server stopped since)
    closing: bool = False
    _limiter: LogLimiter = field(init=False)

    def __post_init__(self) -> None:
        self._limiter = LogLimiter(self.clock, ERROR_LOG_INTERVAL)

    def handle(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        exc = context.get("exception")
        message = context.get("message", "error")
        if self.closing:
            log.info("while shutting down: %s: %s", message, exc)
            return
        held = self._limiter.admit(f"{message}|{type(exc).__name__}|{getattr(exc, 'errno', '')}")
        if held is None:
            return
        repeats = held_note(held)
        if isinstance(exc, OSError):
            log.error("%s: %s%s", message, exc, repeats)
        else:
            log.error("%s%s", message, repeats, exc_info=exc)
