"""`stage-emu view [--control SOCKET]`: a live screen of a running daemon's devices (rich).

It redraws when the daemon pushes an event: each event marks its device stale and that device's
snapshot is read again (one request; events arriving together share one read). Settings that push
no event (a host attaching, line settings, port statistics) show up through a slow full refresh
every FALLBACK_S seconds. No daemon, or a daemon that goes away: one line, exit 1. Ctrl-C: exit 0.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import NoReturn

import click
from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from emulator.control import ControlClient, ControlFailure
from emulator.runtime import SetupError, runtime_dir
from emulator.view import DeviceView, ViewState

#: seconds between full refreshes (list + every snapshot), for changes that push no event
FALLBACK_S = 2.0
#: after an event, how long to keep collecting the ones right behind it before reading snapshots
COALESCE_S = 0.05
#: at most this many events are taken together before the screen is redrawn
COALESCE_MAX = 200
EVENTS_NOTE = "the daemon's control channel names no traffic log, so these are its last events, not exchanges"


def _fail(message: str) -> NoReturn:
    click.echo(f"stage-emu: {message}", err=True)
    sys.exit(1)


def full_refresh(client: ControlClient, state: ViewState, subscribed: set[str]) -> None:
    """Read `list` and every device's snapshot; subscribe to devices not yet subscribed."""
    state.apply_list(client.list())
    for name in state.devices:
        if name not in subscribed:
            client.subscribe(name)
            subscribed.add(name)
        state.apply_snapshot(name, client.snapshot(name))


def update(client: ControlClient, state: ViewState, timeout: float | None) -> set[str]:
    """Wait up to `timeout` s for a pushed event; apply it and those right behind it, then read
    the snapshot of each device they concern. Returns those devices (empty: nothing came)."""
    stale: set[str] = set()
    taken = 0
    for event in client.events(timeout=timeout):
        taken += 1
        device = state.apply_event(event)
        if device is not None:
            stale.add(device)
        break
    if taken:
        for event in client.events(timeout=COALESCE_S):
            device = state.apply_event(event)
            if device is not None:
                stale.add(device)
            taken += 1
            if taken >= COALESCE_MAX:
                break
    for device in sorted(stale):
        if device in state.devices:
            state.apply_snapshot(device, client.snapshot(device))
    return stale


def render_device(view: DeviceView) -> Panel:
    facts = Table.grid(padding=(0, 2))
    facts.add_column(style="bold")
    facts.add_column()
    facts.add_row("positions", view.positions)
    facts.add_row("state", Text(view.busy, style="yellow" if view.busy not in ("idle", "?") else "green"))
    facts.add_row("lcd", "\n".join(view.lcd) or "-")
    facts.add_row("ttl_out0", view.ttl_out0)
    ports = Table("port", "path", "attached", "host line", "timing", "stats", expand=True)
    for row in view.ports:
        ports.add_row(row.port, row.path, row.attached, row.host, row.timing, row.stats)
    events = "\n".join(view.events) if view.events else "(none yet)"
    body = Group(facts, ports, Text("last events", style="bold"), Text(events))
    return Panel(body, title=f"[b]{view.name}[/b] {view.family} ({view.profile})", title_align="left")


def render(state: ViewState) -> RenderableType:
    panels: list[RenderableType] = [render_device(view) for view in state.devices.values()]
    if not panels:
        panels.append(Text("the daemon serves no devices"))
    note = f"Note: {EVENTS_NOTE}. Ctrl-C exits."
    if state.dropped:
        note += f" The daemon dropped {state.dropped} events while the view fell behind."
    panels.append(Text(note, style="dim"))
    return Group(*panels)


def _connect(control: Path | None) -> ControlClient:
    try:
        path = control or runtime_dir() / "control.sock"
    except SetupError as exc:
        _fail(str(exc))
    try:
        return ControlClient(path)
    except OSError as exc:
        _fail(f"cannot reach the daemon at {path}: {exc.strerror or exc} (is `stage-emu serve` running?)")


@click.command("view")
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
def view(control: Path | None) -> None:
    """Live view of a running daemon: each device's positions, busy state, LCD, TTL output, its ports'
    hosts and line settings, and its last events. Redraws on the daemon's events, and fully every
    2 s for changes that push none. Ctrl-C exits."""
    client = _connect(control)
    state = ViewState()
    subscribed: set[str] = set()
    try:
        full_refresh(client, state, subscribed)
        with Live(render(state), console=Console(), auto_refresh=False) as live:
            last_full = time.monotonic()
            while True:
                update(client, state, FALLBACK_S)
                if time.monotonic() - last_full >= FALLBACK_S:
                    full_refresh(client, state, subscribed)
                    last_full = time.monotonic()
                live.update(render(state), refresh=True)
    except KeyboardInterrupt:
        pass
    except ControlFailure as exc:
        _fail(f"the daemon refused a request: {exc}")
    except (OSError, ValueError) as exc:  # closed socket, reset, garbled reply
        _fail(f"lost the daemon: {exc}")
    finally:
        client.close()
