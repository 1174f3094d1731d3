"""`stage-emu serve`: run the daemon on a rig file or on `--profile` devices until a signal stops it."""

from __future__ import annotations

import asyncio
import logging
import sys
from pathlib import Path

import click

from emulator.cli.common import TIME_SCALE, fail
from emulator.cli.profiles import fail_with
from emulator.hosting.control import RequestError
from emulator.hosting.daemon import Daemon, DaemonOptions
from emulator.hosting.rig import load_rig, rig_from_profiles
from emulator.hosting.transports.pty import PortError
from emulator.profiles.profile import bundled_dir
from emulator.profiles.yamlsource import SourceError
from emulator.storage.runtime import SetupError
from emulator.wire_time import TIMINGS

DEFAULT_RIG = "rig.yaml"


@click.command()
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
    "--serial",
    metavar="DEVICE",
    help="Serve the --profile device's main port on this serial port (/dev/ttyUSB0, COM7, a pyserial URL).",
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
    serial: str | None,
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
    has `path` socket://HOST:PORT (--tcp) or rfc2217://HOST:PORT (--rfc2217) and no `pts`; a serial
    port (--serial) has the device as `path` and the device node behind it as `pts`. SIGINT,
    SIGTERM, SIGHUP and SIGQUIT stop it cleanly; SIGUSR1 reopens the traffic log. To run two daemons
    at once, give the second its own --link-dir, --control and --state-dir (or --no-state)."""
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING, format="stage-emu: %(message)s", stream=sys.stderr
    )
    if rig is not None and profiles:
        fail("give either a rig file or --profile options, not both")
    given = [
        (kind, value)
        for kind, value in (("tcp", tcp), ("rfc2217", rfc2217), ("serial", serial))
        if value is not None
    ]
    if len(given) > 1:
        fail(f"give --{given[0][0]} or --{given[1][0]}, not both (a rig file can serve several ports)")
    if no_state and state_dir is not None:
        fail("give --state-dir or --no-state, not both")
    network = given[0] if given else None
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
