"""`stage-emu`: serve a rig, list/validate/describe profiles, talk to a running daemon."""

from __future__ import annotations

import asyncio
import json
import logging
import sys
from pathlib import Path
from typing import Any, NoReturn

import click

from emulator.cli_common import connect, fail
from emulator.cli_gcode import gcode
from emulator.cli_names import NamesHelp
from emulator.cli_plot import plot
from emulator.cli_session import proxy, replay_command
from emulator.cli_trace import trace
from emulator.cli_view import view
from emulator.clock import MAX_SCALE, MAX_STEP, MIN_SCALE, check_scale, check_step
from emulator.control import RequestError
from emulator.control_client import ControlClient, ControlFailure
from emulator.daemon import Daemon, DaemonOptions
from emulator.line import TIMINGS
from emulator.profile import (
    ProfileError,
    bundled_dir,
    bundled_names,
    display_path,
    is_rig,
    load_profile,
    resolve_reference,
)
from emulator.rig import load_rig, rig_from_profiles
from emulator.runtime import SetupError
from emulator.schema import DerivedDefault, plain
from emulator.transports.pty import PortError
from emulator.yamlsource import SourceError, read_source

DEFAULT_RIG = "rig.yaml"


class CheckedFloat(click.ParamType):
    """A float option checked by `check` (finite, in range) with its message as the usage error."""

    name = "number"

    def __init__(self, check: Any, bounds: str) -> None:
        self._check = check
        self._bounds = bounds

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            return float(self._check(float(value)))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return self._bounds


TIME_SCALE = CheckedFloat(check_scale, f"[{MIN_SCALE:g}..{MAX_SCALE:g}]")
STEP_SECONDS = CheckedFloat(check_step, f"[0..{MAX_STEP:g}]")


@click.group()
@click.version_option(package_name="stage-emu")
def main() -> None:
    """Emulate Sutter MP-285 and ASI MS2000 controllers on pseudo-terminals."""


main.add_command(gcode)
main.add_command(plot)
main.add_command(proxy)
main.add_command(replay_command)
main.add_command(trace)
main.add_command(view)


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
    "--tcp",
    metavar="[HOST:]PORT",
    help="Serve the --profile device's main port as a raw TCP socket here (default host 127.0.0.1).",
)
@click.option(
    "--rfc2217",
    metavar="[HOST:]PORT",
    help="Serve the --profile device's main port over RFC 2217 (telnet serial port) here.",
)
@click.option(
    "--timing", type=click.Choice(TIMINGS), help="Pace every port at its baud rate, or deliver at once."
)
@click.option(
    "--time-scale", type=TIME_SCALE, default=1.0, show_default=True, help="Device seconds per wall second."
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
    help="Where devices keep non-volatile memory (default $XDG_STATE_HOME/stage-emu, else "
    "~/.local/state/stage-emu). A device's memory there belongs to one daemon at a time.",
)
@click.option(
    "--no-state",
    is_flag=True,
    help="Keep the devices' non-volatile memory in memory only, for this run: nothing is read from or "
    "saved to a state directory (e.g. beside a daemon that owns it).",
)
@click.option("--control", type=click.Path(dir_okay=False, path_type=Path), help="Control socket path.")
@click.option(
    "--link-dir", type=click.Path(file_okay=False, path_type=Path), help="Directory for default port links."
)
@click.option("-v", "--verbose", is_flag=True, help="Log host attach/detach and other details.")
def serve(
    rig: Path | None,
    profiles: tuple[str, ...],
    tcp: str | None,
    rfc2217: str | None,
    timing: str | None,
    time_scale: float,
    ready_file: Path | None,
    log_traffic: Path | None,
    state_dir: Path | None,
    no_state: bool,
    control: Path | None,
    link_dir: Path | None,
    verbose: bool,
) -> None:
    """Serve RIG (default: the bundled rig, one MP-285 and one MS2000) until Ctrl-C.

    Prints one JSON line per port: {"device", "profile", "port", "path", "pts", "transport"}. Only
    `path` is stable: `pts` changes when a port is re-created (a `disconnect` fault); a network port
    has `path` socket://HOST:PORT (--tcp) or rfc2217://HOST:PORT (--rfc2217) and no `pts`. SIGINT,
    SIGTERM, SIGHUP and SIGQUIT stop it cleanly; SIGUSR1 reopens the traffic log. To run two daemons
    at once, give the second its own --link-dir, --control and --state-dir (or --no-state)."""
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING, format="stage-emu: %(message)s", stream=sys.stderr
    )
    if rig is not None and profiles:
        fail("give either a rig file or --profile options, not both")
    if tcp is not None and rfc2217 is not None:
        fail("give --tcp or --rfc2217, not both (a rig file can serve several ports)")
    if no_state and state_dir is not None:
        fail("give --state-dir or --no-state, not both")
    network = ("tcp", tcp) if tcp is not None else ("rfc2217", rfc2217) if rfc2217 is not None else None
    if network is not None and not profiles:
        fail(f"--{network[0]} goes with --profile (in a rig file, give the port `transport: {network[0]}`)")
    try:
        if profiles:
            spec = rig_from_profiles(list(profiles), network)
        else:
            spec = load_rig(rig if rig is not None else bundled_dir() / DEFAULT_RIG)
        options = DaemonOptions(
            timing, time_scale, ready_file, log_traffic, state_dir, control, link_dir, no_state
        )
        code = asyncio.run(Daemon(spec, options).run())
    except SourceError as exc:
        fail_with(exc)
    except (PortError, RequestError, SetupError) as exc:
        fail(str(exc))
    except OSError as exc:  # anything else the system refused at start: one line, no traceback
        fail(f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
    sys.exit(code)


@main.command()
def profiles() -> None:
    """List the bundled profiles."""
    names = bundled_names()
    width = max((len(name) for name in names), default=0) + 2
    for name in names:
        try:
            profile = load_profile(name)
        except ProfileError as exc:
            click.echo(f"{name:<{width}}(invalid: {exc})")
            continue
        click.echo(f"{name:<{width}}{profile.family:<8} {profile.description}")


@main.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def validate(files: tuple[Path, ...]) -> None:
    """Check profile or rig FILES; exit 1 with every problem, one `file:line: key: problem` line each,
    in file order (a file that cannot be read or parsed at all is one problem)."""
    failed = False
    for path in files:
        try:
            if is_rig(read_source(path).data):
                load_rig(path)
            else:
                load_profile(str(path.absolute()))
            click.echo(f"{path}: ok")
        except SourceError as exc:
            for line in problem_lines(exc):
                click.echo(line, err=True)
            failed = True
    sys.exit(1 if failed else 0)


def problem_lines(exc: SourceError) -> list[str]:
    """Every problem a file was refused for, one line each, in file order."""
    return exc.report() if isinstance(exc, ProfileError) else [str(exc)]


def fail_with(exc: SourceError) -> NoReturn:
    """`fail` with every problem of a refused file, each on its own `stage-emu:` line."""
    *first, last = problem_lines(exc)
    for line in first:
        click.echo(f"stage-emu: {line}", err=True)
    fail(last)


@main.command()
@click.argument("profile")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
def describe(profile: str, as_json: bool) -> None:
    """Print every knob of PROFILE: value, default, allowed values (type and range), rule and meaning."""
    try:
        loaded = load_profile(profile)
    except ProfileError as exc:
        hint = _rig_hint(profile)
        if hint:
            fail(hint)
        fail_with(exc)
    rows = loaded.describe()
    if as_json:
        click.echo(json.dumps([row.__dict__ for row in rows], indent=2, default=str, ensure_ascii=False))
        return
    click.echo(f"{loaded.name} ({loaded.family}): {loaded.description}")
    table = []
    for row in rows:
        value = json.dumps(row.value, ensure_ascii=False)
        if isinstance(row.default, DerivedDefault):
            default, mark = str(row.default), ""
        else:
            default = json.dumps(plain(row.default), ensure_ascii=False)
            mark = "" if row.value == plain(row.default) else "  *"
        table.append((row.path, value, default, _clipped(row.type), row.rule, row.doc + mark))
    # every column as wide as its widest cell, so long values keep the columns aligned
    widths = [max(len(cells[i]) for cells in table) for i in range(5)]
    for path, value, default, allowed, rule, doc in table:
        w_path, w_value, w_default, w_allowed, w_rule = widths
        click.echo(
            f"{path:<{w_path}}  {value:<{w_value}}  default {default:<{w_default}}  "
            f"allowed {allowed:<{w_allowed}}  {rule:<{w_rule}}  {doc}"
        )


#: `describe`'s allowed-values column is cut here (`--json` has every type in full)
ALLOWED_WIDTH = 48


def _clipped(text: str) -> str:
    return text if len(text) <= ALLOWED_WIDTH else text[: ALLOWED_WIDTH - 1] + "…"


def _rig_hint(ref: str) -> str:
    """If REF names a rig rather than a profile, say so and name the rig's profiles."""
    path = resolve_reference(ref, None)
    try:
        data = read_source(path).data
    except SourceError:
        return ""
    if not is_rig(data):
        return ""
    devices = data["devices"] if isinstance(data["devices"], list) else []
    names = [d["profile"] for d in devices if isinstance(d, dict) and isinstance(d.get("profile"), str)]
    return f"{display_path(path)} is a rig, not a profile; describe one of its profiles: {', '.join(names)}"


@main.group()
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


if __name__ == "__main__":
    main()
