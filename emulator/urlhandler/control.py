"""The control channel of an in-process device (`port.control` of a `stageemu://` port): the daemon's
requests, answered in this process by the daemon's own dispatch (emulator/hosting/control.py), with the
socket client's methods (emulator/control_client.py). Inputs, observables, snapshots, faults,
resets and the clock work as on a daemon; `subscribe` queues the device's pushed events here, and
`events(timeout)` waits for them as a host read does (in virtual time, device time passes). Traffic
subscriptions need a daemon (its traffic log records are for `stage-emu view` and `ctl watch`).
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from emulator.control_client import ControlFailure, ControlRequests
from emulator.hosting.control import ControlServer

if TYPE_CHECKING:
    from emulator.urlhandler.hosted import HostedDevice


class HostedControl(ControlRequests):
    """Control requests for one in-process device, named `name` (default: its profile's name, as a
    daemon serving one `--profile` names it)."""

    def __init__(self, device: HostedDevice, name: str | None = None) -> None:
        self._device = device
        self.name = name or device.name
        # never started: no socket, only the dispatch (`handle_line`)
        self._server = ControlServer(Path(self.name), {self.name: device.runner}, device.clock)
        self._events: deque[dict[str, Any]] | None = None

    def request(self, request: dict[str, Any]) -> Any:
        if "device" in request and request.get("op") in ("subscribe", "unsubscribe"):
            return self._subscription(request)
        line = json.dumps(request).encode()
        reply = json.loads(self._device.call(lambda: self._server.handle_line(line)))
        if not reply["ok"]:
            raise ControlFailure(reply["error"])
        return reply["result"]

    def events(self, timeout: float | None = None) -> Iterator[dict[str, Any]]:
        queue = self._events
        if queue is None:
            return
        device = self._device
        while device.wait_for(lambda: bool(queue), device.deadline(timeout)):
            yield queue.popleft()

    def _subscription(self, request: dict[str, Any]) -> bool:
        if request["device"] != self.name:
            raise ControlFailure(f"no device {request['device']!r}; devices: {self.name}")
        if request.get("traffic"):
            raise ControlFailure("traffic subscriptions need a daemon (stage-emu serve)")
        if request["op"] == "subscribe" and self._events is None:
            self._events = self._device.subscribe(self.name)
        elif request["op"] == "unsubscribe" and self._events is not None:
            self._device.unsubscribe(self._events)
            self._events = None
        return True
