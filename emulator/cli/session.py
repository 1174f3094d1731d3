"""`stage-emu proxy` (record a host's session with a real controller) and `stage-emu replay` (play
its host side again on the emulator or on a controller, and diff the replies). Bad input is one
line on stderr: exit 1 for the proxy; 2 for replay, whose 1 means "the replies differ"."""

from __future__ import annotations

import asyncio
import logging
import re
import sys
from dataclasses import replace
from pathlib import Path

import click

from emulator.cli.common import fail
from emulator.device import LineSettings
from emulator.hosting.transports.pty import PortError
from emulator.profiles.profile import ProfileError, load_profile
from emulator.storage.runtime import SetupError, runtime_dir
from emulator.tools.progress import Progress
from emulator.tools.proxy import Proxy, ProxyError, ProxyOptions
from emulator.tools.readers import ReadError
from emulator.tools.replay import (
    DEFAULT_TOLERANCE_S,
    ReplayError,
    ReplayOptions,
    check_profile,
    emulator_url,
    open_port,
    replay,
)
from emulator.tools.session import FAMILIES, Session, SessionError, load_session, save_session
from emulator.wire_time import REALISTIC, TIMINGS

#: where `--save-test NAME` puts a session: the conformance suite replays every file there
TESTS_DIR = Path("tests/conformance")
TEST_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
BAUD = click.IntRange(50, 4_000_000)


@click.command("proxy")
@click.option("--real", required=True, metavar="PORT", help="The controller: a device path or pyserial URL.")
@click.option("--device", "family", type=click.Choice(FAMILIES), required=True, help="Its protocol.")
@click.option("--profile", metavar="NAME", help="Profile it matches (default: the --device one).")
@click.option("--baud", type=BAUD, help="Its baud rate, if not the profile's.")
@click.option(
    "--link",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Where the host's port appears (default: <runtime dir>/proxy-DEVICE).",
)
@click.option(
    "--record",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The session file to write (must not exist).",
)
@click.option("-v", "--verbose", is_flag=True, help="Log host open/close and other details.")
def proxy(
    real: str,
    family: str,
    profile: str | None,
    baud: int | None,
    link: Path | None,
    record: Path,
    verbose: bool,
) -> None:
    """Put a pseudo-terminal in front of the controller on PORT and record a session.

    Prints one JSON line, {"device", "profile", "path", "pts", "real", "record"}: open `path` with
    the host program as the controller's own port. Every byte is forwarded both ways as it comes
    and recorded with its time; the host's baud rate, stop bits and flow control are set on the real
    port too. Ctrl-C (SIGINT), SIGTERM or SIGHUP stops it and completes the session file."""
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING, format="stage-emu: %(message)s", stream=sys.stderr
    )
    name = profile or family
    try:
        loaded = load_profile(name)
    except ProfileError as exc:
        fail(str(exc))
    if loaded.family != family:
        fail(f"profile {name} is for the {loaded.family}, not the {family}")
    if record.exists() or record.is_symlink():
        fail(f"{record}: already exists; remove it or choose another file")
    device = loaded.line
    line = LineSettings(
        baud=baud or device.baud,
        data_bits=device.data_bits,
        parity=device.parity,
        stop_bits=device.stop_bits,
        rtscts=device.flow_control == "rtscts",
        xonxoff=device.flow_control == "xonxoff",
    )
    try:
        link = (link or runtime_dir() / f"proxy-{family}").expanduser().absolute()
        recorder = Proxy(ProxyOptions(real, family, name, line, link, record))
        asyncio.run(recorder.run())
    except (ProxyError, PortError, SessionError, SetupError) as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
    except KeyboardInterrupt:  # before the signal handlers are in place: nothing recorded yet
        sys.exit(130)
    if recorder.failure:
        fail(f"{recorder.failure} (the session so far is in {record})")
    click.echo(f"stage-emu: {recorder.exchanges} exchanges recorded in {record}", err=True)


@click.command("replay")
@click.argument("session_file", metavar="SESSION", type=click.Path(path_type=Path))
@click.option("--profile", metavar="NAME", help="Emulate this profile (default: the session's).")
@click.option("--port", "port_url", metavar="PORT", help="Replay on this port (a controller) instead.")
@click.option("--baud", type=BAUD, help="The --port controller's baud rate, if not the session's.")
@click.option(
    "--timing",
    type=click.Choice(TIMINGS),
    default=REALISTIC,
    show_default=True,
    help="The emulator's timing; with fast, reply timing is not compared.",
)
@click.option(
    "--tolerance-ms",
    type=click.FloatRange(0, 60_000),
    default=DEFAULT_TOLERANCE_S * 1000,
    show_default=True,
    help="How far a reply's first and last byte may move.",
)
@click.option(
    "--save-test",
    metavar="NAME|PATH",
    help=f"Also save the session as a conformance case ({TESTS_DIR}/DEVICE/sessions/NAME.jsonl).",
)
def replay_command(
    session_file: Path,
    profile: str | None,
    port_url: str | None,
    baud: int | None,
    timing: str,
    tolerance_ms: float,
    save_test: str | None,
) -> None:
    """Play the host side of SESSION (from `stage-emu proxy --record`) on the emulator, or on a
    controller with --port, and print each exchange whose reply differs, in bytes or in timing
    beyond the tolerance, then a summary line. The session is read a line at a time, never whole;
    on a terminal, stderr shows the lines checked, then the host writes replayed.

    Exit status: 0 no difference; 1 differences; 2, with one line on stderr, bad input: SESSION
    not a regular file, empty, or not a session (a line too long or nested too deep included), or
    a profile or port that cannot be used."""
    logging.basicConfig(level=logging.WARNING, format="stage-emu: %(message)s", stream=sys.stderr)
    try:
        with Progress(f"stage-emu replay: checking {session_file}") as progress:
            session = load_session(session_file, progress.tick)
        header = session.header
        if port_url is None:
            name = profile or header.profile
            check_profile(name, header.device)
            _note_baud(name, header.line.baud)
            url = emulator_url(name, timing)
        else:
            url = port_url
        target = _test_path(save_test, session) if save_test else None
        if not session.complete:
            click.echo(f"stage-emu: {session_file}: no end record (the proxy was stopped short)", err=True)
        line = header.line if baud is None else replace(header.line, baud=baud)
        port = open_port(url, line)
        try:
            options = ReplayOptions(tolerance_ms / 1000, timing=port_url is not None or timing == REALISTIC)
            with Progress(f"stage-emu replay: replaying {session_file}", "host writes") as progress:
                result = replay(session, port, options, progress.tick)
        finally:
            port.close()
    except (ReadError, ReplayError) as exc:
        fail(str(exc), 2)
    for text in result.report():
        click.echo(text)
    timing_note = f"tolerance {tolerance_ms:g} ms" if options.timing else "timing not compared"
    click.echo(f"{result.summary(url)} ({timing_note})")
    if target is not None:
        _save(session, target, result.ok)
    sys.exit(0 if result.ok else 1)


def _note_baud(profile: str, recorded: int | None) -> None:
    emulated = load_profile(profile).line.baud
    if recorded is not None and recorded != emulated:
        click.echo(
            f"stage-emu: the session's controller ran at {recorded} baud, profile {profile} at "
            f"{emulated}: expect garbled replies (use a profile with the controller's baud rate)",
            err=True,
        )


def _test_path(value: str, session: Session) -> Path:
    """NAME: tests/conformance/DEVICE/sessions/NAME.jsonl (from the checkout); else a path."""
    if "/" in value or value.endswith(".jsonl"):
        path = Path(value)
    elif not TEST_NAME.fullmatch(value):
        raise SessionError(f"--save-test {value!r}: a name of letters, digits, '.', '_' and '-', or a path")
    elif not TESTS_DIR.is_dir():
        raise SessionError(f"--save-test {value}: no {TESTS_DIR} here; run from the stage-emu checkout")
    else:
        path = TESTS_DIR / session.header.device / "sessions" / f"{value}.jsonl"
    if path.exists():
        raise SessionError(f"--save-test: {path} already exists; choose another name")
    return path


def _save(session: Session, path: Path, ok: bool) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        count = save_session(session, path)
    except (SessionError, OSError) as exc:
        fail(f"--save-test: {exc}", 2)
    click.echo(f"saved as a conformance case: {path} ({count} exchanges)")
    if not ok:
        click.echo("(its replay differs: the case fails until the emulator matches the recording)")
