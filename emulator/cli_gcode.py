"""`stage-emu gcode FILE --port PATH`: run a G-code program on an MS-2000 (MS-TRACER-5).

The interpreter is the client library's (protocols/clients/gcode); this is only its command line:
read the file, plan from where the stage is, run, and say what went wrong as one line naming the
file and line, never a traceback.
"""

from __future__ import annotations

import math
from pathlib import Path

import click
import serial

from emulator.cli_common import fail
from protocols.clients import MS2000
from protocols.clients.gcode import (
    ExecutionError,
    GcodeError,
    GcodeExecutor,
    Step,
    parse_program,
    read_program,
)

#: MS-TRACER-2: Tracer runs at 115200; the other rates MS-2 allows serve other personalities
BAUDS = ("115200", "28800", "19200", "9600")


class Positive(click.ParamType):
    """A finite number above 0."""

    def __init__(self, name: str) -> None:
        self.name = name

    def convert(self, value: object, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            number = float(str(value))
        except ValueError:
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number) or number <= 0:
            self.fail(f"{value!r} must be a number above 0", param, ctx)
        return number


FACTOR = Positive("factor")
SECONDS = Positive("seconds")


@click.command("gcode")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--port", metavar="PATH", help="The controller's serial port (not needed with --dry-run).")
@click.option("--baud", type=click.Choice(BAUDS), default="115200", show_default=True, help="Baud rate.")
@click.option("--xyz-scale", type=FACTOR, default=1.0, show_default=True, help="Multiplies every length.")
@click.option("--speed-scale", type=FACTOR, default=1.0, show_default=True, help="Multiplies every F.")
@click.option("--timeout", type=SECONDS, default=2.0, show_default=True, help="Seconds to wait for a reply.")
@click.option("--dry-run", is_flag=True, help="Print the planned steps from X=Y=Z=0 and send nothing.")
@click.option("-v", "--verbose", is_flag=True, help="Print each step as it is sent.")
def gcode(
    file: Path,
    port: str | None,
    baud: str,
    xyz_scale: float,
    speed_scale: float,
    timeout: float,
    dry_run: bool,
    verbose: bool,
) -> None:
    """Run the G-code program FILE on an MS-2000 stage controller with high-level commands.

    Supported: G00-G03 (arcs by I/J/K or R), G04 P (ms), G15/G16, G17-G19, G20/G21, G90/G91,
    M03/M05 (TTL output on/off), F per minute. Coordinates are stage millimetres (inches under G20)
    from the stage's zero; the program starts where the stage is."""
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        fail(f"{file}: does not exist")
    except (OSError, UnicodeDecodeError) as exc:
        fail(f"{file}: cannot read it: {exc}")
    try:
        if dry_run:
            for step in parse_program(text, xyz_scale=xyz_scale, speed_scale=speed_scale):
                click.echo(str(step))
            return
        if port is None:
            fail("--port PATH is required (or --dry-run to only plan)")
        read_program(text)  # a malformed line is reported before the stage is touched
        _run(text, str(port), int(baud), timeout, xyz_scale, speed_scale, verbose)
    except GcodeError as exc:
        fail(f"{file}:{exc.line}: {exc.message}")
    except ExecutionError as exc:
        fail(f"{file}:{exc.line}: {exc.message}" if exc.line is not None else f"{port}: {exc.message}")
    except KeyboardInterrupt:
        fail("interrupted: a running program was halted and its TTL output switched off")


def _run(
    text: str, port: str, baud: int, timeout: float, xyz_scale: float, speed_scale: float, verbose: bool
) -> None:
    try:
        stage = MS2000(port, baud, timeout)
    except (serial.SerialException, OSError) as exc:
        fail(f"{port}: cannot open the port: {exc}")
    with stage:
        executor = GcodeExecutor(stage)
        counts = executor.counts_per_mm()
        click.echo("counts per mm: " + " ".join(f"{a}={c:g}" for a, c in counts.items()))
        steps = parse_program(
            text, start=executor.start_position(), xyz_scale=xyz_scale, speed_scale=speed_scale
        )

        def show(step: Step) -> None:
            click.echo(str(step))

        summary = executor.run(steps, show if verbose else None)
    click.echo(
        f"done: {summary.moves} moves, {summary.dwells} dwells, {summary.outputs} output changes "
        f"in {summary.seconds:.1f} s"
    )
