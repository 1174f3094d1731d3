"""`stage-emu capture --port P --device D [-o FILE]`: a profile from a real controller
(emulator/tools/capture).

Only this command line lives here: options, the output file (created mode 0600, never overwritten
without `--force`), one line for every failure. The capture itself is imported when it runs.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import click

from emulator.cli.common import fail

DEVICES = ("mp285", "ms2000")
STOP_BITS = ("1", "1.5", "2")


class Seconds(click.ParamType):
    name = "seconds"

    def convert(self, value: object, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            number = float(str(value))
        except ValueError:
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number) or not 0 < number <= 3600:
            self.fail(f"{value!r} must be above 0 and at most 3600", param, ctx)
        return number


@click.command("capture")
@click.option("--port", metavar="PORT", help="The controller's port: a device or any pyserial URL.")
@click.option("--device", type=click.Choice(DEVICES), required=True, help="The controller's family.")
@click.option(
    "-o", "--output", type=click.Path(path_type=Path), help="Write the profile here (default: stdout)."
)
@click.option("--force", is_flag=True, help="Overwrite OUTPUT if it exists.")
@click.option("--dry-run", is_flag=True, help="Print every command a capture sends; open no port.")
@click.option("--baud", type=int, default=9600, show_default=True, help="Baud rate the port is opened at.")
@click.option(
    "--parity", type=click.Choice(("none", "even", "odd")), default="none", show_default=True, help="Parity."
)
@click.option("--stop-bits", type=click.Choice(STOP_BITS), default="1", show_default=True, help="Stop bits.")
@click.option("--rtscts", is_flag=True, help="RTS/CTS flow control (the MP-285A's USB port).")
@click.option(
    "--timeout", type=Seconds(), default=1.0, show_default=True, help="Seconds to wait for a reply."
)
def capture(
    port: str | None,
    device: str,
    output: Path | None,
    force: bool,
    dry_run: bool,
    baud: int,
    parity: str,
    stop_bits: str,
    rtscts: bool,
    timeout: float,
) -> None:
    """Read a controller's identity and settings with read-only commands and write them as a
    profile that extends the closest bundled one and sets only what differs.

    Nothing is moved, set, saved or reset: docs/capture.md lists every command sent, --dry-run
    prints them. Replies that are not understood, and queries that get no reply, are kept as
    comments in the profile. The profile is loaded and validated before it is written.

    Exit status: 0 written; 1, with one line on stderr, when the port cannot be opened, the first
    query gets no reply at all, or OUTPUT exists (without --force) or cannot be written; 2 for a
    bad option, or a captured profile that does not validate (a bug: please report it)."""
    from emulator.tools.capture import FAMILIES, CaptureBug, CaptureError, LineOptions
    from emulator.tools.capture import capture as run_capture
    from emulator.tools.capture import dry_run as plan

    if dry_run:
        for text in plan(device):
            click.echo(text)
        return
    if port is None:
        raise click.UsageError("--port PORT is required (or --dry-run to list the commands)")
    line = LineOptions(baud, parity, float(stop_bits) if stop_bits == "1.5" else int(stop_bits), rtscts)
    problem = FAMILIES[device].line_problem(line)
    if problem is not None:
        raise click.UsageError(problem)
    if output is not None and not force and (output.exists() or output.is_symlink()):
        fail(f"{output} exists; --force to overwrite it")
    try:
        result = run_capture(port, device, line, timeout, output.stem if output else None)
    except CaptureError as exc:
        fail(str(exc))
    except CaptureBug as exc:
        fail(f"{exc} (a bug of stage-emu capture: please report it)", 2)
    except KeyboardInterrupt:
        fail("interrupted: nothing written")
    if output is None:
        click.echo(result.text, nl=False)
    else:
        _write(output, result.text, force)
    settled = result.settled
    where = "" if output is None else f" in {output}"
    click.echo(
        f"stage-emu: {len(result.sent)} queries, {len(settled.readings)} fields read; the profile{where} "
        f"extends {settled.parent.name} and sets {len(settled.chosen)} of them"
        + (f" ({len(result.notes)} {'note' if len(result.notes) == 1 else 'notes'})" if result.notes else ""),
        err=True,
    )


def _write(path: Path, text: str, force: bool) -> None:
    """`text` into `path`, created mode 0600; with `force`, through a temporary file beside it that
    replaces it, so a failed write leaves the old file whole."""
    data = text.encode("utf-8")
    target = path.with_name(f".{path.name}.{os.getpid()}.tmp") if force else path
    try:
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        fail(f"{target} exists; --force to overwrite it")
    except OSError as exc:
        fail(f"{target}: cannot create it: {exc.strerror or exc}")
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(data)
        if force:
            os.replace(target, path)
    except OSError as exc:
        if force:
            target.unlink(missing_ok=True)
        fail(f"{path}: cannot write it: {exc.strerror or exc}")
