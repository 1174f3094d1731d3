"""Control channel: JSON lines over a Unix socket (mode 0600); its Python client is
emulator/control_client.py.

One request per line, one reply per request, replies in order:

    {"id": 1, "op": "list"}                                        -> devices and their ports
    {"id": 2, "device": "stage", "op": "snapshot", "path": "axes.X"}
    {"id": 3, "device": "stage", "get": "lcd"}                     -> a device observable
    {"id": 3, "device": "stage", "op": "names"}                    -> its inputs and observables
    {"id": 4, "device": "stage", "in": "joystick", "x": 0.5}       -> a device input
    {"id": 5, "device": "stage", "op": "reset"}                    -> fresh model from the profile
    {"id": 6, "device": "stage", "op": "power_cycle"}
    {"id": 7, "device": "stage", "op": "fault", "port": "main", "fault": "drop", "count": 2}
    {"id": 8, "op": "clock", "scale": 10}     also {"op": "pause"}, {"op": "resume"},
                                              {"op": "step", "seconds": 0.5}
    {"id": 9, "device": "stage", "op": "subscribe"}                -> then {"ev": ..., "device": ...} lines
    {"id": 10, "device": "stage", "op": "subscribe", "traffic": true}  -> then {"ev": "traffic", ...}
                  lines, its traffic log records (rx/tx, trafficlog.py); "unsubscribe" undoes either

A model formats its traffic only while a traffic log is kept or a connection takes its records. Pushed
lines are bounded per connection (SUBSCRIBER_BACKLOG): a slow reader loses lines, never stalls a device.

Replies: `{"id": .., "ok": true, "result": ..}` or `{"id": .., "ok": false, "error": "sentence"}`.
The device vocabulary (`in`, `get`, `ev` names) belongs to each device model.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import stat
from collections.abc import Collection
from pathlib import Path
from typing import Any

from emulator.device import ControlError
from emulator.hosting.clock import ControlledClock, check_scale, check_step
from emulator.hosting.runner import DeviceRunner
from emulator.storage.runtime import SetupError, check_socket_path, socket_is_live

log = logging.getLogger("stage_emu.control")

MAX_REQUEST = 1 << 20
#: Connections served at once; more are told so and closed (each costs the daemon a descriptor).
MAX_CLIENTS = 64
#: Unsent event bytes a subscriber may have queued; past this its events are dropped (and counted)
#: until it reads again, so a client that never reads cannot grow the daemon.
SUBSCRIBER_BACKLOG = 64 * 1024
#: Seconds a stopping server gives its clients to take what is queued for them before it cuts them
#: off; a connection that is not over by then would be cancelled with the loop, with a traceback.
STOP_GRACE_S = 1.0


class RequestError(Exception):
    """A request that cannot be served; its message is the reply's `error`."""


class ControlServer:
    def __init__(
        self,
        path: Path,
        runners: dict[str, DeviceRunner],
        clock: ControlledClock,
        traffic: Path | None = None,
    ) -> None:
        self.path = path
        self._runners = runners
        self._clock = clock
        self._traffic_log = traffic  # named in `list`
        self._server: asyncio.AbstractServer | None = None
        #: per device, the connections subscribed to its events, and those to its traffic records
        self._subscribers: dict[str, set[asyncio.StreamWriter]] = {}
        self._watchers: dict[str, set[asyncio.StreamWriter]] = {}
        self._clients: set[asyncio.StreamWriter] = set()
        #: the task serving each connection: `stop` waits for them, so none is left to be cancelled
        self._tasks: set[asyncio.Task[None]] = set()
        #: events dropped per subscriber connection since it last kept up
        self._dropped: dict[asyncio.StreamWriter, int] = {}
        #: (st_dev, st_ino) of the socket this server bound: the only thing `stop` may remove
        self._bound: tuple[int, int] | None = None
        #: the instant the last `step` request stepped the clock to, until its reply is sent; and
        #: the replies waiting for devices behind the clock to get there (emulator/hosting/lag.py)
        self._step_target: float | None = None
        self._step_waiters: list[asyncio.Future[None]] = []
        for runner in runners.values():
            runner.device_time.on_slice = self._wake_steps

    async def start(self) -> None:
        check_socket_path(self.path, "--control")
        _claim_socket_path(self.path)
        old_umask = os.umask(0o177)
        try:
            self._server = await asyncio.start_unix_server(
                self._serve, path=str(self.path), limit=MAX_REQUEST
            )
        except OSError as exc:
            raise SetupError(f"--control {self.path}: cannot listen: {exc.strerror or exc}") from None
        finally:
            os.umask(old_umask)
        info = self.path.lstat()
        self._bound = (info.st_dev, info.st_ino)
        os.chmod(self.path, 0o600)

    async def stop(self) -> None:
        """Close the socket and every connection, and wait until each connection's task is over.

        A connection still open when the loop ends has its task cancelled, and asyncio (3.11) then
        logs a CancelledError traceback from the stream's done-callback: so each client is closed
        (what is queued for it is still sent), given STOP_GRACE_S, then cut off."""
        if self._server is not None:
            self._server.close()
        for writer in list(self._clients):
            writer.close()
        self._wake_steps()  # a step's reply still waiting goes to a closed connection
        if self._tasks:
            await asyncio.wait(self._tasks, timeout=STOP_GRACE_S)
        for writer in list(self._clients):
            writer.transport.abort()  # a client that does not read: its queue goes unsent
        if self._tasks:
            await asyncio.wait(self._tasks, timeout=STOP_GRACE_S)
        if self._server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 1.0)
        if self._bound is not None:
            with contextlib.suppress(OSError):
                info = self.path.lstat()
                if (info.st_dev, info.st_ino) == self._bound:
                    self.path.unlink()
            self._bound = None

    def publish(self, device: str, event: dict[str, Any]) -> None:
        """Push a device event to every connection subscribed to that device's events."""
        self._push(device, self._subscribers.get(device, ()), {**event, "device": device})

    def _push(self, device: str, writers: Collection[asyncio.StreamWriter], message: dict[str, Any]) -> None:
        """A subscriber that does not read loses lines past SUBSCRIBER_BACKLOG; once it reads again it
        first gets `{"ev": "dropped", "count": N}` for what it missed. `_serve` forgets closed ones."""
        if not writers:  # the common case: nobody listens, so nothing is encoded
            return
        line = (json.dumps(message) + "\n").encode()
        for writer in writers:
            if writer.is_closing():
                continue
            if writer.transport.get_write_buffer_size() > SUBSCRIBER_BACKLOG:
                dropped = self._dropped.get(writer, 0)
                if dropped == 0:
                    log.warning("control: a subscriber to %s is not reading; dropping its events", device)
                self._dropped[writer] = dropped + 1
                continue
            dropped = self._dropped.pop(writer, 0)
            if dropped:
                log.warning("control: a subscriber to %s caught up after %d dropped events", device, dropped)
                notice = {"ev": "dropped", "device": device, "count": dropped}
                writer.write((json.dumps(notice) + "\n").encode())
            writer.write(line)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)
        if len(self._clients) >= MAX_CLIENTS:
            writer.write(_reply(None, error=f"too many control connections (at most {MAX_CLIENTS})"))
            with contextlib.suppress(ConnectionError):
                await writer.drain()
            writer.close()
            return
        self._clients.add(writer)
        try:
            while True:
                try:
                    line = await reader.readline()
                except (asyncio.LimitOverrunError, ValueError):
                    writer.write(_reply(None, error=f"request longer than {MAX_REQUEST} bytes"))
                    break
                if not line or writer.is_closing():  # `stop` closed it: what it still sent goes unserved
                    break
                reply = self.handle_line(line, writer)
                target, self._step_target = self._step_target, None
                if target is not None:
                    await self._until_devices_reach(target, writer)
                writer.write(reply)
                await writer.drain()
        except ConnectionError:
            pass
        finally:
            for subscribers in self._subscribers.values():
                subscribers.discard(writer)
            for name, watchers in self._watchers.items():
                if writer in watchers:
                    self._watch(self._runners[name], writer, False)
            self._dropped.pop(writer, None)
            self._clients.discard(writer)
            writer.close()

    async def _until_devices_reach(self, target: float, writer: asyncio.StreamWriter) -> None:
        """A `step` is answered once every device has run up to the instant it stepped to: a device
        with much work in that time runs it over several turns of the loop (emulator/hosting/lag.py), and a
        host that asks it something after the step expects the stepped state."""
        loop = asyncio.get_running_loop()
        while not writer.is_closing() and any(
            r.clock.behind and r.device.now < target for r in self._runners.values()
        ):
            waiter: asyncio.Future[None] = loop.create_future()
            self._step_waiters.append(waiter)
            await waiter

    def _wake_steps(self) -> None:
        waiters, self._step_waiters = self._step_waiters, []
        for waiter in waiters:
            if not waiter.done():
                waiter.set_result(None)

    def handle_line(self, line: bytes, writer: asyncio.StreamWriter | None = None) -> bytes:
        try:
            request = json.loads(line, parse_constant=_no_constant)
        except ValueError as exc:  # bad JSON, bad UTF-8, NaN/Infinity
            return _reply(None, error=f"not a JSON object: {exc}")
        if not isinstance(request, dict):
            return _reply(None, error="a request must be a JSON object")
        ident = request.get("id")
        try:
            return _reply(ident, result=self._dispatch(request, writer))
        except (RequestError, ControlError, ValueError) as exc:
            return _reply(ident, error=str(exc))
        except Exception as exc:  # a model bug must not take the daemon down
            log.exception("control request %r failed", request)
            return _reply(ident, error=f"internal error: {type(exc).__name__}: {exc}")

    def _dispatch(self, request: dict[str, Any], writer: asyncio.StreamWriter | None) -> Any:
        op = request.get("op")
        if "device" not in request:
            return self._global(op, request)
        runner = self._runner(request["device"])
        if "in" in request:
            name = _name(request["in"], "in")
            params = {k: v for k, v in request.items() if k not in ("id", "device", "in")}
            return runner.call(lambda now: runner.device.control_input(name, params, now))
        if "get" in request:
            name = _name(request["get"], "get")
            if name == "ports":
                return {
                    ch.name: ch.transport.path if ch.transport else None for ch in runner.channels.values()
                }
            return runner.call(lambda now: runner.device.observe(name, now))
        if op == "snapshot":
            return _at_path(runner.call(lambda now: runner.device.snapshot(now)), request.get("path"))
        if op == "names":
            return runner.device.control_names()
        if op == "reset":
            runner.reset()
            return True
        if op == "power_cycle":
            return runner.call(lambda now: runner.device.control_input("power_cycle", {}, now))
        if op == "fault":
            params = {k: v for k, v in request.items() if k not in ("id", "device", "op", "port", "fault")}
            return runner.inject(str(request.get("port", "main")), str(request.get("fault")), params)
        if op in ("subscribe", "unsubscribe"):
            if writer is None:
                raise RequestError(f"{op} needs a connection")
            traffic = request.get("traffic", False)
            if not isinstance(traffic, bool):
                raise RequestError(f"'traffic' must be true or false, got {traffic!r}")
            if traffic:
                self._watch(runner, writer, op == "subscribe")
            else:
                subscribers = self._subscribers.setdefault(runner.name, set())
                (subscribers.add if op == "subscribe" else subscribers.discard)(writer)
            return True
        raise RequestError(
            f"unknown device request {op!r}; use 'in', 'get' or an op: "
            "snapshot, names, reset, power_cycle, fault, subscribe, unsubscribe"
        )

    def _watch(self, runner: DeviceRunner, writer: asyncio.StreamWriter, on: bool) -> None:
        """Add or remove a subscriber to the runner's traffic records; the runner hands them over
        (and its model explains) only while the device has one."""
        name = runner.name
        watchers = self._watchers.setdefault(name, set())
        had = bool(watchers)
        (watchers.add if on else watchers.discard)(writer)
        if bool(watchers) != had:
            runner.watch_traffic(
                (lambda entry: self._push(name, watchers, {"ev": "traffic", **entry})) if watchers else None
            )

    def _global(self, op: Any, request: dict[str, Any]) -> Any:
        if op == "list":
            log = None if self._traffic_log is None else str(self._traffic_log)
            return [{**_describe(runner), "traffic_log": log} for runner in self._runners.values()]
        if op == "clock":
            if "scale" in request:
                self._clock.set_scale(check_scale(request["scale"]))
            return self._clock_state()
        if op == "pause":
            self._clock.pause()
            return self._clock_state()
        if op == "resume":
            self._clock.resume()
            return self._clock_state()
        if op == "step":
            if "seconds" not in request:
                raise RequestError("step needs 'seconds'")
            self._clock.step(check_step(request["seconds"]))
            self._step_target = self._clock.now()
            return self._clock_state()
        if op is None:
            raise RequestError("a request needs 'op' (list, clock, pause, resume, step) or a 'device'")
        raise RequestError(f"unknown op {op!r}; without a device: list, clock, pause, resume, step")

    def _clock_state(self) -> dict[str, Any]:
        return {"now": self._clock.now(), "scale": self._clock.scale, "paused": self._clock.paused}

    def _runner(self, name: Any) -> DeviceRunner:
        runner = self._runners.get(name) if isinstance(name, str) else None
        if runner is None:
            raise RequestError(f"no device {name!r}; devices: {', '.join(self._runners) or 'none'}")
        return runner


def _describe(runner: DeviceRunner) -> dict[str, Any]:
    profile = runner.device.profile
    ports = []
    for ch in runner.channels.values():
        ports.append(
            {
                "port": ch.name,
                "path": ch.transport.path if ch.transport else None,
                "pts": ch.transport.device_path if ch.transport else None,
                "transport": ch.transport.kind if ch.transport else None,
                "attached": ch.attached,
                "host": ch.host.describe() if ch.host else None,
                # a serial line is paced by its UARTs, whatever the port's timing says
                "timing": "serial line" if ch.transport and ch.transport.wire_paces else ch.timing,
                "faults": ch.faults.describe(),
                "stats": ch.stats.describe(),
            }
        )
    return {
        "device": runner.name,
        "family": profile.family,
        "profile": profile.name,
        "storage_error": runner.device.storage_error,
        # device seconds the model is behind the clock, having more work than the CPU can do
        # (emulator/hosting/lag.py); `lagging` while it has fallen behind within the last second
        "behind_s": runner.clock.behind,
        "lagging": runner.lag.lagging,
        "ports": ports,
    }


def _name(value: Any, key: str) -> str:
    if not isinstance(value, str) or not value:
        raise RequestError(f"'{key}' must be a non-empty string, got {value!r}")
    return value


def _at_path(state: Any, path: Any) -> Any:
    if path in (None, ""):
        return state
    if not isinstance(path, str):
        raise RequestError(f"path must be a dotted string, got {path!r}")
    for part in path.split("."):
        if isinstance(state, dict) and part in state:
            state = state[part]
        elif isinstance(state, list) and part.isdigit() and int(part) < len(state):
            state = state[int(part)]
        else:
            raise RequestError(f"no {part!r} in snapshot path {path!r}")
    return state


def _reply(ident: Any, result: Any = None, error: str | None = None) -> bytes:
    body: dict[str, Any] = {"id": ident, "ok": error is None}
    if error is None:
        body["result"] = result
    else:
        body["error"] = error
    return (json.dumps(body, default=str) + "\n").encode()


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def _claim_socket_path(path: Path) -> None:
    """Make room for the control socket: only a socket nobody listens on (a crashed daemon's) may
    be removed; anything else at the path is refused."""
    try:
        info = path.lstat()
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(info.st_mode):
        raise SetupError(
            f"--control {path} exists and is not a socket; refusing to replace it "
            "(pass --control another path)"
        )
    if socket_is_live(path):
        raise SetupError(f"{path} is in use by a running stage-emu; stop it or pass --control another path")
    path.unlink()
