"""The control channel's blocking Python client (stdlib only): what `stage-emu ctl`, `view`, the
launcher and the tests use to talk to a running daemon (emulator/hosting/control.py has the protocol).

`ControlRequests` is the client's vocabulary on top of one `request` call; `ControlClient` sends it
over the daemon's socket, and an in-process port answers the same (emulator/urlhandler/control.py)."""

from __future__ import annotations

import builtins
import json
import socket
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Any


class ControlFailure(Exception):
    """The daemon answered a request with an error."""


class ControlRequests(ABC):
    """The control channel's requests as methods, on top of `request` (one reply per request)."""

    @abstractmethod
    def request(self, request: dict[str, Any]) -> Any:
        """Send one request; its `result`, or ControlFailure with the daemon's `error`."""

    @abstractmethod
    def events(self, timeout: float | None = None) -> Iterator[dict[str, Any]]:
        """Pushed events (after `subscribe`), buffered ones first; stops at `timeout` of silence."""

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


class ControlClient(ControlRequests):
    """Blocking client for a daemon's control socket (stdlib only)."""

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
