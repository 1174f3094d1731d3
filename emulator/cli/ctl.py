"""`stage-emu ctl`: talk to a running daemon over its control channel (emulator/control_client.py).

Needs only the control client: `ctl list` and the others must start as fast as the interpreter and
click allow, so nothing here imports the daemon, the models or the profiles (the names in
`ctl input --help` and `ctl get --help` are computed by emulator/cli/names.py only when shown)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from emulator.cli.common import STEP_SECONDS, TIME_SCALE, connect, fail
from emulator.cli.names import NamesHelp
from emulator.control_client import ControlClient, ControlFailure


@click.group()
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
@click.pass_context
def ctl(ctx: click.Context, control: Path | None) -> None:
    """Talk to a running daemon over its control channel."""
    ctx.obj = control


def _client(ctx: click.Context) -> ControlClient:
    return connect(ctx.obj)


def _run(ctx: click.Context, request: dict[str, Any]) -> None:
    with _client(ctx) as client:
        try:
            result = client.request(request)
        except ControlFailure as exc:
            fail(str(exc))
    click.echo(json.dumps(result, indent=2))


def _params(pairs: tuple[str, ...]) -> dict[str, Any]:
    """`key=value` words; values parsed as JSON when they are JSON (numbers, true, lists), else text."""
    params: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            fail(f"expected key=value, got {pair!r}")
        try:
            params[key] = json.loads(value)
        except json.JSONDecodeError:
            params[key] = value
    return params


@ctl.command("list")
@click.pass_context
def ctl_list(ctx: click.Context) -> None:
    """Devices, ports and attached hosts."""
    _run(ctx, {"op": "list"})


@ctl.command("get", cls=NamesHelp, kind="observables")
@click.argument("device")
@click.argument("name", required=False)
@click.pass_context
def ctl_get(ctx: click.Context, device: str, name: str | None) -> None:
    """Read observable NAME of DEVICE; without NAME, list DEVICE's inputs and observables."""
    _run(ctx, {"device": device, "op": "names"} if name is None else {"device": device, "get": name})


@ctl.command("snapshot")
@click.argument("device")
@click.argument("path", required=False)
@click.pass_context
def ctl_snapshot(ctx: click.Context, device: str, path: str | None) -> None:
    """Full state of DEVICE (or the part at dotted PATH)."""
    _run(ctx, {"device": device, "op": "snapshot", "path": path})


@ctl.command("input", cls=NamesHelp, kind="inputs")
@click.argument("device")
@click.argument("name")
@click.argument("params", nargs=-1)
@click.pass_context
def ctl_input(ctx: click.Context, device: str, name: str, params: tuple[str, ...]) -> None:
    """Drive input NAME of DEVICE, e.g. `ctl input stage joystick x=0.5 y=0`."""
    _run(ctx, {"device": device, "in": name, **_params(params)})


@ctl.command("reset")
@click.argument("device")
@click.pass_context
def ctl_reset(ctx: click.Context, device: str) -> None:
    """Replace DEVICE by a fresh model from its profile."""
    _run(ctx, {"device": device, "op": "reset"})


@ctl.command("power-cycle")
@click.argument("device")
@click.pass_context
def ctl_power_cycle(ctx: click.Context, device: str) -> None:
    """Switch DEVICE off and on."""
    _run(ctx, {"device": device, "op": "power_cycle"})


@ctl.command("fault")
@click.argument("device")
@click.argument("fault", type=click.Choice(["disconnect", "hang", "drop", "corrupt", "latency", "clear"]))
@click.argument("params", nargs=-1)
@click.option("--port", default="main", show_default=True)
@click.pass_context
def ctl_fault(ctx: click.Context, device: str, fault: str, params: tuple[str, ...], port: str) -> None:
    """Inject a port fault: disconnect [seconds=S], hang [seconds=S], drop [count=N], corrupt [count=N],
    latency ms=M, clear. Numbers come as key=value (JSON numbers)."""
    _run(ctx, {"device": device, "op": "fault", "port": port, "fault": fault, **_params(params)})


@ctl.command("clock")
@click.option("--scale", type=TIME_SCALE, help="Device seconds per wall second.")
@click.option("--pause", "action", flag_value="pause", help="Stop device time.")
@click.option("--resume", "action", flag_value="resume", help="Restart device time.")
@click.option("--step", type=STEP_SECONDS, help="Advance device time by this many seconds.")
@click.pass_context
def ctl_clock(ctx: click.Context, scale: float | None, action: str | None, step: float | None) -> None:
    """Show or change device time."""
    if action is not None:
        _run(ctx, {"op": action})
    elif step is not None:
        _run(ctx, {"op": "step", "seconds": step})
    else:
        _run(ctx, {"op": "clock"} if scale is None else {"op": "clock", "scale": scale})


@ctl.command("watch")
@click.argument("device")
@click.option("--traffic", is_flag=True, help="Its traffic records (what the traffic log writes) instead.")
@click.pass_context
def ctl_watch(ctx: click.Context, device: str, traffic: bool) -> None:
    """Print DEVICE's pushed events (or, with --traffic, its traffic records) until Ctrl-C (exit 0);
    a daemon that stops or goes away ends it with one line and exit 1."""
    with _client(ctx) as client:
        try:
            client.subscribe(device, traffic=traffic)
        except ControlFailure as exc:
            fail(str(exc))
        except (OSError, ValueError) as exc:  # closed, reset, a garbled line: as `stage-emu view`
            fail(f"lost the daemon: {exc}")
        events = client.events(timeout=None)
        try:
            while True:
                try:
                    event = next(events)
                except (OSError, ValueError) as exc:
                    fail(f"lost the daemon: {exc}")
                click.echo(json.dumps(event))  # not in that try: a closed stdout is no lost daemon
        except KeyboardInterrupt:
            pass


@ctl.command("raw")
@click.argument("request")
@click.pass_context
def ctl_raw(ctx: click.Context, request: str) -> None:
    """Send one JSON REQUEST as is and print the result, e.g.
    `stage-emu ctl raw '{"device": "ms2000", "op": "snapshot", "path": "axes.X"}'`
    (the request forms are in the README's control channel section)."""
    try:
        body = json.loads(request)
    except json.JSONDecodeError as exc:
        fail(f"not JSON: {exc}")
    if not isinstance(body, dict):
        fail("a request must be a JSON object")
    _run(ctx, body)
