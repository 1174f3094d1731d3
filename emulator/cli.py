"""`stage-emu`: serve a rig, list/validate/describe profiles, talk to a running daemon."""

from __future__ import annotations

import asyncio
import json
import logging
import sys
from pathlib import Path
from typing import Any

import click

from emulator.control import ControlClient, ControlFailure, RequestError
from emulator.daemon import Daemon, DaemonOptions
from emulator.line import TIMINGS
from emulator.profile import ProfileError, bundled_dir, bundled_names, load_profile
from emulator.rig import load_rig, rig_from_profiles
from emulator.schema import DerivedDefault, plain
from emulator.transports.pty import PortError, runtime_dir
from emulator.yamlsource import SourceError, load_located

DEFAULT_RIG = "rig.yaml"


def _fail(message: str) -> None:
    click.echo(f"stage-emu: {message}", err=True)
    sys.exit(1)


@click.group()
@click.version_option(package_name="stage-emu")
def main() -> None:
    """Emulate Sutter MP-285 and ASI MS2000 controllers on pseudo-terminals."""


@main.command()
@click.argument("rig", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--profile",
    "profiles",
    multiple=True,
    metavar="NAME[:LINK]",
    help="Serve one device with this profile (repeatable) instead of a rig.",
)
@click.option(
    "--timing", type=click.Choice(TIMINGS), help="Pace every port at its baud rate, or deliver at once."
)
@click.option(
    "--time-scale", type=float, default=1.0, show_default=True, help="Device seconds per wall second."
)
@click.option(
    "--ready-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the ports as JSON here once ready.",
)
@click.option(
    "--log-traffic", type=click.Path(dir_okay=False, path_type=Path), help="Append every byte as JSON lines."
)
@click.option(
    "--state-dir",
    type=click.Path(file_okay=False, path_type=Path),
    help="Where devices keep non-volatile memory.",
)
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
@click.option(
    "--link-dir", type=click.Path(file_okay=False, path_type=Path), help="Directory for default port links."
)
@click.option("-v", "--verbose", is_flag=True, help="Log host attach/detach and other details.")
def serve(
    rig: Path | None,
    profiles: tuple[str, ...],
    timing: str | None,
    time_scale: float,
    ready_file: Path | None,
    log_traffic: Path | None,
    state_dir: Path | None,
    control: Path | None,
    link_dir: Path | None,
    verbose: bool,
) -> None:
    """Serve RIG (default: the bundled rig, one MP-285 and one MS2000) until Ctrl-C.

    Prints one JSON line per port: {"device", "profile", "port", "path", "pts"}."""
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING, format="stage-emu: %(message)s", stream=sys.stderr
    )
    if time_scale <= 0:
        _fail(f"--time-scale must be > 0, got {time_scale}")
    if rig is not None and profiles:
        _fail("give either a rig file or --profile options, not both")
    try:
        if profiles:
            spec = rig_from_profiles(list(profiles))
        else:
            spec = load_rig(rig if rig is not None else bundled_dir() / DEFAULT_RIG)
        options = DaemonOptions(timing, time_scale, ready_file, log_traffic, state_dir, control, link_dir)
        code = asyncio.run(Daemon(spec, options).run())
    except (SourceError, PortError, RequestError) as exc:
        _fail(str(exc))
    sys.exit(code)


@main.command()
def profiles() -> None:
    """List the bundled profiles."""
    for name in bundled_names():
        try:
            profile = load_profile(name)
        except ProfileError as exc:
            click.echo(f"{name:<22} (invalid: {exc})")
            continue
        click.echo(f"{name:<22} {profile.family:<8} {profile.description}")


@main.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
def validate(files: tuple[Path, ...]) -> None:
    """Check profile or rig FILES; exit 1 with the problems."""
    failed = False
    for path in files:
        try:
            data = load_located(path.read_text(), str(path)).data
            if isinstance(data, dict) and "devices" in data:
                load_rig(path)
            else:
                load_profile(str(path.absolute()))
            click.echo(f"{path}: ok")
        except OSError as exc:
            click.echo(f"{path}: cannot read: {exc.strerror or exc}", err=True)
            failed = True
        except SourceError as exc:
            click.echo(str(exc), err=True)
            failed = True
    sys.exit(1 if failed else 0)


@main.command()
@click.argument("profile")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
def describe(profile: str, as_json: bool) -> None:
    """Print every knob of PROFILE: value, default, rule and meaning."""
    try:
        loaded = load_profile(profile)
    except ProfileError as exc:
        _fail(str(exc))
    rows = loaded.describe()
    if as_json:
        click.echo(json.dumps([row.__dict__ for row in rows], indent=2, default=str, ensure_ascii=False))
        return
    click.echo(f"{loaded.name} ({loaded.family}): {loaded.description}")
    width = max(len(row.path) for row in rows)
    for row in rows:
        value = json.dumps(row.value, ensure_ascii=False)
        if isinstance(row.default, DerivedDefault):
            default, mark = str(row.default), ""
        else:
            default = json.dumps(plain(row.default), ensure_ascii=False)
            mark = "" if row.value == plain(row.default) else "  *"
        click.echo(f"{row.path:<{width}}  {value:<14} default {default:<14} {row.rule:<11} {row.doc}{mark}")


@main.group()
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
@click.pass_context
def ctl(ctx: click.Context, control: Path | None) -> None:
    """Talk to a running daemon over its control channel."""
    ctx.obj = control


def _client(ctx: click.Context) -> ControlClient:
    path = ctx.obj or runtime_dir() / "control.sock"
    try:
        return ControlClient(path)
    except OSError as exc:
        _fail(f"cannot reach the daemon at {path}: {exc.strerror or exc} (is `stage-emu serve` running?)")
    raise AssertionError


def _run(ctx: click.Context, request: dict[str, Any]) -> None:
    with _client(ctx) as client:
        try:
            result = client.request(request)
        except ControlFailure as exc:
            _fail(str(exc))
    click.echo(json.dumps(result, indent=2))


def _params(pairs: tuple[str, ...]) -> dict[str, Any]:
    """`key=value` words; values parsed as JSON when they are JSON (numbers, true, lists), else text."""
    params: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            _fail(f"expected key=value, got {pair!r}")
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


@ctl.command("get")
@click.argument("device")
@click.argument("name")
@click.pass_context
def ctl_get(ctx: click.Context, device: str, name: str) -> None:
    """Read observable NAME of DEVICE."""
    _run(ctx, {"device": device, "get": name})


@ctl.command("snapshot")
@click.argument("device")
@click.argument("path", required=False)
@click.pass_context
def ctl_snapshot(ctx: click.Context, device: str, path: str | None) -> None:
    """Full state of DEVICE (or the part at dotted PATH)."""
    _run(ctx, {"device": device, "op": "snapshot", "path": path})


@ctl.command("input")
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
    latency ms=M, clear."""
    _run(ctx, {"device": device, "op": "fault", "port": port, "fault": fault, **_params(params)})


@ctl.command("clock")
@click.option("--scale", type=float, help="Device seconds per wall second.")
@click.option("--pause", "action", flag_value="pause", help="Stop device time.")
@click.option("--resume", "action", flag_value="resume", help="Restart device time.")
@click.option("--step", type=float, help="Advance device time by this many seconds.")
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
@click.pass_context
def ctl_watch(ctx: click.Context, device: str) -> None:
    """Print DEVICE's pushed events until Ctrl-C."""
    with _client(ctx) as client:
        try:
            client.subscribe(device)
        except ControlFailure as exc:
            _fail(str(exc))
        try:
            for event in client.events(timeout=None):
                click.echo(json.dumps(event))
        except KeyboardInterrupt:
            pass


@ctl.command("raw")
@click.argument("request")
@click.pass_context
def ctl_raw(ctx: click.Context, request: str) -> None:
    """Send one JSON REQUEST as is."""
    try:
        body = json.loads(request)
    except json.JSONDecodeError as exc:
        _fail(f"not JSON: {exc}")
    if not isinstance(body, dict):
        _fail("a request must be a JSON object")
    _run(ctx, body)


if __name__ == "__main__":
    main()
