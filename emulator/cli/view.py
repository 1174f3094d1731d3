"""`stage-emu view [--control SOCKET]`: a live screen of a running daemon's devices (rich).

It subscribes to each device's events and traffic records, and redraws when the daemon pushes one:
each marks its device stale and that device's snapshot is read again (one request; what arrives
within COALESCE_S shares one read and one redraw). Settings that push nothing (a host attaching,
line settings, port statistics) show up through a slow full refresh every FALLBACK_S seconds. No
daemon, or a daemon that goes away: one line, exit 1. Ctrl-C: exit 0.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from pathlib import Path

import click
from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from emulator.cli.common import connect, fail
from emulator.control_client import ControlClient, ControlFailure
from emulator.tools.trace import REPLY_WAIT_S
from emulator.tools.view import DeviceView, ExchangeRow, ViewState

#: seconds between full refreshes (list + every snapshot), for changes that push no event
FALLBACK_S = 2.0
#: after an event, how long to keep collecting the ones behind it before reading snapshots
COALESCE_S = 0.05
#: at most this many events are taken together before the screen is redrawn
COALESCE_MAX = 200
#: how a flag is drawn (a flag not listed: bold)
FLAG_STYLES = {"STRAY": "yellow", "UNSOLICITED": "cyan"}


def full_refresh(client: ControlClient, state: ViewState, subscribed: set[str]) -> None:
    """Read `list` and every device's snapshot; subscribe to the events and traffic records of
    devices not yet subscribed."""
    state.apply_list(client.list())
    for name in state.devices:
        if name not in subscribed:
            client.subscribe(name)
            client.subscribe(name, traffic=True)
            subscribed.add(name)
        state.apply_snapshot(name, client.snapshot(name))


def update(client: ControlClient, state: ViewState, timeout: float | None) -> set[str]:
    """Wait up to `timeout` s for a pushed event; apply it and those behind it for COALESCE_S more
    (at most COALESCE_MAX), then read the snapshot of each device they concern, and show requests
    the daemon has not answered for a while. Returns those devices (empty: nothing came)."""
    stale: set[str] = set()
    event = next(client.events(timeout=timeout), None)
    deadline = time.monotonic() + COALESCE_S
    taken = 0
    while event is not None:
        device = state.apply_event(event)
        if device is not None:
            stale.add(device)
        taken += 1
        left = deadline - time.monotonic()
        if taken >= COALESCE_MAX or left <= 0:
            break
        event = next(client.events(timeout=left), None)
    state.expire(time.time() - REPLY_WAIT_S)
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
    ports = Table("port", expand=True)
    ports.add_column("path", overflow="fold")  # never cut short: it is what a host opens
    for header in ("attached", "host line", "timing", "stats"):
        ports.add_column(header)
    for row in view.ports:
        ports.add_row(row.port, row.path, row.attached, row.host, row.timing, row.stats)
    events = "\n".join(view.events) if view.events else "(none yet)"
    body = Group(
        facts,
        ports,
        Text("last exchanges", style="bold"),
        render_exchanges(view.exchanges),
        Text("last events", style="bold"),
        Text(events),
    )
    return Panel(body, title=f"[b]{view.name}[/b] {view.family} ({view.profile})", title_align="left")


def render_exchanges(rows: Iterable[ExchangeRow]) -> RenderableType:
    """One line per exchange: device time, port, flag, `request -> reply`, latency."""
    table = Table(box=None, padding=(0, 1), show_header=False, expand=True)
    table.add_column(justify="right", no_wrap=True)
    table.add_column(no_wrap=True)
    table.add_column(no_wrap=True)
    table.add_column(ratio=1, no_wrap=True, overflow="ellipsis")
    table.add_column(justify="right", no_wrap=True)
    for row in rows:
        flag = Text(row.flag, style=FLAG_STYLES.get(row.flag, "bold red"))
        said = " -> ".join(part for part in (row.request, row.reply) if part)
        said = said if row.request else f"-> {said}"
        latency = "" if row.latency_ms is None else f"{row.latency_ms:.1f} ms"
        table.add_row(f"{row.t:.3f}", row.port, flag, said, latency)
    return table if table.row_count else Text("(none yet)")


def render(state: ViewState) -> RenderableType:
    panels: list[RenderableType] = [render_device(view) for view in state.devices.values()]
    if not panels:
        panels.append(Text("the daemon serves no devices"))
    if state.traffic_log:
        note = f"Traffic log: {state.traffic_log} (`stage-emu trace --follow` reads all of it)."
    else:
        note = "The daemon keeps no traffic log; its devices explain their traffic while the view watches."
    note += " Ctrl-C exits."
    if state.dropped:
        note += f" The daemon dropped {state.dropped} events or records while the view fell behind."
    panels.append(Text(note, style="dim"))
    return Group(*panels)


@click.command("view")
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
def view(control: Path | None) -> None:
    """Live view of a running daemon: each device's positions, busy state, LCD, TTL output, its ports'
    hosts and line settings, its last exchanges decoded, and its last events. Redraws on the
    daemon's events and traffic, and fully every 2 s for changes that push none. Ctrl-C exits."""
    client = connect(control)
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
        fail(f"the daemon refused a request: {exc}")
    except (OSError, ValueError) as exc:  # closed socket, reset, garbled reply
        fail(f"lost the daemon: {exc}")
    finally:
        client.close()
