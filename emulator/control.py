"""Control channel: JSON lines over a Unix socket (mode 0600), and its Python client.

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
import builtins
import contextlib
import json
import logging
import os
import socket
import stat
from collections import deque
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

from emulator.clock import ScaledClock, check_scale, check_step
from emulator.device import ControlError
from emulator.runner import DeviceRunner
from emulator.runtime import SetupError, check_socket_path, socket_is_live

log = logging.getLogger("stage_emu.control")

MAX_REQUEST = 1 << 20
#: Connections served at once; more are told so and closed (each costs the daemon a descriptor).
MAX_CLIENTS = 64
#: Unsent event bytes a subscriber may have queued; past this its events are dropped (and counted)
#: until it reads again, so a client that never reads cannot grow the daemon.
SUBSCRIBER_BACKLOG = 64 * 1024


class RequestError(Exception):
    """A request that cannot be served; its message is the reply's `error`."""


class ControlServer:
    def __init__(
        self, path: Path, runners: dict[str, DeviceRunner], clock: ScaledClock, traffic: Path | None = None
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
        #: events dropped per subscriber connection since it last kept up
        self._dropped: dict[asyncio.StreamWriter, int] = {}
        #: (st_dev, st_ino) of the socket this server bound: the only thing `stop` may remove
        self._bound: tuple[int, int] | None = None

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
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 1.0)
        for writer in list(self._clients):
            writer.close()
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
                if not line:
                    break
                writer.write(self.handle_line(line, writer))
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
                "timing": ch.timing,
                "faults": ch.faults.describe(),
                "stats": ch.stats.describe(),
            }
        )
    return {
        "device": runner.name,
        "family": profile.family,
        "profile": profile.name,
        "storage_error": runner.device.storage_error,
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


class ControlFailure(Exception):
    """The daemon answered a request with an error."""


class ControlClient:
    """Blocking client for the control channel (stdlib only)."""

    def __init__(self, path: str | Path, timeout: float = 10.0) -> None:
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.settimeout(timeout)
        self._sock.connect(str(path))
        self._buffer = b""
        self._next_id = 0
        self._events: deque[dict[str, Any]] = deque()

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> ControlClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request(self, request: dict[str, Any]) -> Any:
        self._next_id += 1
        ident = self._next_id
        self._sock.sendall((json.dumps({**request, "id": ident}) + "\n").encode())
        while True:
            message = self._read_message()
            if "ev" in message:
                self._events.append(message)
                continue
            if message.get("id") != ident:
                continue
            if not message.get("ok"):
                raise ControlFailure(message.get("error", "unknown error"))
            return message.get("result")

    def _read_message(self) -> dict[str, Any]:
        while b"\n" not in self._buffer:
            chunk = self._sock.recv(65536)
            if not chunk:
                raise ConnectionError("control channel closed")
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def events(self, timeout: float | None = None) -> Iterator[dict[str, Any]]:
        """Pushed events (after `subscribe`), buffered ones first; stops at `timeout` of silence."""
        while True:
            while self._events:
                yield self._events.popleft()
            previous = self._sock.gettimeout()
            self._sock.settimeout(timeout)
            try:
                message = self._read_message()
            except TimeoutError:
                return
            finally:
                self._sock.settimeout(previous)
            if "ev" in message:
                yield message

    def list(self) -> list[dict[str, Any]]:
        return self.request({"op": "list"})

    def get(self, device: str, name: str) -> Any:
        return self.request({"device": device, "get": name})

    def input(self, device: str, input_name: str, /, **params: Any) -> Any:
        """Set a device input; positional-only so an input may itself take a `name` parameter."""
        return self.request({"device": device, "in": input_name, **params})

    def names(self, device: str) -> dict[str, builtins.list[str]]:  # `list` is a method here
        """The device's input and observable names."""
        return self.request({"device": device, "op": "names"})

    def snapshot(self, device: str, path: str | None = None) -> Any:
        return self.request({"device": device, "op": "snapshot", "path": path})

    def reset(self, device: str) -> Any:
        return self.request({"device": device, "op": "reset"})

    def power_cycle(self, device: str) -> Any:
        return self.request({"device": device, "op": "power_cycle"})

    def fault(self, device: str, fault: str, port: str = "main", **params: Any) -> Any:
        return self.request({"device": device, "op": "fault", "port": port, "fault": fault, **params})

    def subscribe(self, device: str, traffic: bool = False) -> Any:
        """Pushed events of `device` (see `events`); with `traffic`, its traffic records instead."""
        return self.request({"device": device, "op": "subscribe", "traffic": traffic})

    def clock(self, scale: float | None = None) -> Any:
        return self.request({"op": "clock"} if scale is None else {"op": "clock", "scale": scale})

    def pause(self) -> Any:
        return self.request({"op": "pause"})

    def resume(self) -> Any:
        return self.request({"op": "resume"})

    def step(self, seconds: float) -> Any:
        return self.request({"op": "step", "seconds": seconds})
