"""The data behind `stage-emu view`: pure functions from the control channel's `list`, device
snapshots, pushed events and traffic records to the rows the screen shows (emulator/cli/view.py
draws them).

Traffic records (`{"ev": "traffic", ...}`, the traffic log's rx/tx records) are paired into
exchanges by `stage-emu trace`'s own Tracer (emulator/tools/trace.py); each becomes an `ExchangeRow`.
"""

from __future__ import annotations

import json
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from emulator.device import LOST
from emulator.hosting.trafficlog import RX
from emulator.tools.trace import (
    REPLY_WAIT_S,
    Exchange,
    Item,
    Record,
    TraceOptions,
    Tracer,
    readable,
    record_from,
    reply_gist,
)

#: device events kept per device for the "last events" panel
EVENTS_KEPT = 4
#: exchanges (and traffic outside any) kept per device for the "last exchanges" panel
EXCHANGES_KEPT = 8
#: the pushed event that carries a traffic record
TRAFFIC = "traffic"
#: events that fire many times per move and say nothing a snapshot does not
NOISY_EVENTS = frozenset({"move"})


@dataclass
class PortRow:
    port: str
    path: str
    attached: str
    host: str
    timing: str
    stats: str


@dataclass(frozen=True)
class ExchangeRow:
    """One line of the "last exchanges" panel: what the host sent (the model's summary, else the
    bytes), what came back, and `flag` for anything but a plain exchange (STRAY, GARBLED, LOST,
    UNSOLICITED; `reply LOST` for an answer that never reached the host)."""

    t: float
    port: str
    flag: str
    request: str
    reply: str
    latency_ms: float | None = None


@dataclass
class DeviceView:
    """What the screen shows of one device."""

    name: str
    family: str = "?"
    profile: str = "?"
    ports: list[PortRow] = field(default_factory=list)
    positions: str = "-"
    busy: str = "?"
    lcd: list[str] = field(default_factory=list)
    ttl_out0: str = "-"
    events: deque[str] = field(default_factory=lambda: deque(maxlen=EVENTS_KEPT))
    exchanges: deque[ExchangeRow] = field(default_factory=lambda: deque(maxlen=EXCHANGES_KEPT))


@dataclass
class ViewState:
    devices: dict[str, DeviceView] = field(default_factory=dict)
    #: events and traffic records the daemon dropped because the view fell behind
    dropped: int = 0
    #: the daemon's traffic log (from `list`), None when it keeps none
    traffic_log: str | None = None
    tracer: Tracer = field(default_factory=lambda: Tracer(TraceOptions(events="none")))

    def apply_list(self, listing: list[dict[str, Any]]) -> None:
        """Devices and their ports from `list`; devices no longer listed go away."""
        names = [str(entry.get("device")) for entry in listing]
        self.traffic_log = next((str(e["traffic_log"]) for e in listing if e.get("traffic_log")), None)
        for name in list(self.devices):
            if name not in names:
                del self.devices[name]
        for entry, name in zip(listing, names, strict=True):
            view = self.devices.setdefault(name, DeviceView(name))
            view.family = str(entry.get("family", "?"))
            view.profile = str(entry.get("profile", "?"))
            view.ports = [port_row(port) for port in entry.get("ports", [])]

    def apply_snapshot(self, device: str, snapshot: dict[str, Any]) -> None:
        view = self.devices.setdefault(device, DeviceView(device))
        view.positions = positions(snapshot)
        view.busy = busy(snapshot)
        view.lcd = lcd_lines(snapshot)
        view.ttl_out0 = ttl_out0(snapshot)

    def apply_event(self, event: dict[str, Any]) -> str | None:
        """Record a pushed event; returns the device whose snapshot is now stale (None: none)."""
        device = event.get("device")
        if not isinstance(device, str):
            return None
        if event.get("ev") == TRAFFIC:
            try:
                record = record_from(event)
            except ValueError:
                return None
            self._add(self.tracer.pair(record))
            return device
        if event.get("ev") == "dropped":
            self.dropped += int(event.get("count", 0))
        view = self.devices.setdefault(device, DeviceView(device))
        if event.get("ev") not in NOISY_EVENTS:
            view.events.append(event_line(event))
        return device

    def expire(self, written_before: float) -> None:
        """Show requests written (wall clock) before `written_before` still without a reply."""
        self._add(self.tracer.expire_items(written_before, f"no reply within {REPLY_WAIT_S:g} s"))

    def _add(self, items: list[Item]) -> None:
        for item in items:
            device = item.request.device if isinstance(item, Exchange) else item.device
            self.devices.setdefault(device, DeviceView(device)).exchanges.append(exchange_row(item))


def exchange_row(item: Item) -> ExchangeRow:
    """An exchange, or traffic outside any (a lone record), as a row."""
    if not isinstance(item, Exchange):
        kind = item.kind or "bytes"
        told = (item.summary or "").removeprefix(f"{kind}: ")
        text = f"{readable(item.data)} {told}".strip() if item.data else told
        sent, got = (text, "") if item.direction == RX else ("", text)
        return ExchangeRow(item.t, item.port or "-", kind.upper(), sent, got)
    request, reply = item.request, item.reply
    flags = ["STRAY"] if request.kind == "stray" else []
    said = _said(request)
    if reply is None:
        return ExchangeRow(request.t, request.port or "-", " ".join(flags), said, item.missing)
    shown = readable(reply.data)
    gist = reply_gist(reply.summary, request.summary, shown[1:-1])
    answer = gist or shown
    if reply.kind == LOST:
        flags.append("reply LOST")
        answer = f"{shown} ({gist})" if gist else shown
    latency = (reply.t - request.t) * 1000
    return ExchangeRow(request.t, request.port or "-", " ".join(flags), said, answer, latency)


def _said(request: Record) -> str:
    """A request as the device read it: its summary (a stray unit's bytes with it), else the bytes."""
    if request.kind == "stray":
        return f"{readable(request.data)} {request.summary or ''}".rstrip()
    return request.summary or readable(request.data)


def port_row(port: dict[str, Any]) -> PortRow:
    stats = port.get("stats") or {}
    faults = [k for k, v in (port.get("faults") or {}).items() if v]
    stat_text = " ".join(f"{k}={v}" for k, v in stats.items() if v) or "-"
    if faults:
        stat_text += " faults: " + ",".join(faults)
    return PortRow(
        port=str(port.get("port", "?")),
        path=str(port.get("path") or "-"),
        attached="yes" if port.get("attached") else "no",
        host=str(port.get("host") or "-"),
        timing=str(port.get("timing") or "-"),
        stats=stat_text,
    )


def positions(snapshot: dict[str, Any]) -> str:
    """MP-285: `position.um`; MS2000: each axis's `user_mm`."""
    position = snapshot.get("position")
    if isinstance(position, dict) and isinstance(position.get("um"), dict):
        return " ".join(f"{axis}={value:.2f}µm" for axis, value in position["um"].items())
    axes = snapshot.get("axes")
    if isinstance(axes, dict):
        return " ".join(
            f"{axis}={state.get('user_mm', 0.0):.4f}mm"
            for axis, state in axes.items()
            if isinstance(state, dict)
        )
    return "-"


def busy(snapshot: dict[str, Any]) -> str:
    """MS2000: `busy`; MP-285: its `state` (IDLE, MOVING, ...)."""
    if "busy" in snapshot:
        return "busy" if snapshot["busy"] else "idle"
    state = snapshot.get("state")
    return str(state).lower() if state is not None else "?"


def lcd_lines(snapshot: dict[str, Any]) -> list[str]:
    """MS2000 `lcd` or MP-285 `display` lines."""
    lines = snapshot.get("lcd", snapshot.get("display"))
    return [str(line) for line in lines] if isinstance(lines, list) else []


def ttl_out0(snapshot: dict[str, Any]) -> str:
    if "ttl_out0" not in snapshot:
        return "-"
    text = "high" if snapshot["ttl_out0"] else "low"
    pwm = snapshot.get("ttl_out0_pwm")
    return f"{text} (pwm {pwm:g})" if isinstance(pwm, (int, float)) and pwm else text


def event_line(event: dict[str, Any]) -> str:
    """`t=1.250 ttl_out0 level=1`: device time, event name, the rest as key=value."""
    rest = " ".join(
        f"{key}={json.dumps(value, separators=(',', ':'))}"
        for key, value in event.items()
        if key not in ("ev", "device", "t")
    )
    t = event.get("t")
    stamp = f"t={t:.3f} " if isinstance(t, (int, float)) else ""
    return f"{stamp}{event.get('ev', '?')} {rest}".rstrip()
