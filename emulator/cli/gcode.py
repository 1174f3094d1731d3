"""`stage-emu gcode FILE --port PATH`: run a G-code program on an MS-2000 (MS-TRACER-5).

The interpreter is the client library's (protocols/clients/gcode); this is only its command line:
read the file, plan from where the stage is, run, and say what went wrong as one line naming the
file and line, never a traceback. The file is read a line at a time through the bounded reader
(emulator/tools/readers.py), never whole: `--dry-run` prints the plan as it is made, and a run reads the
file three times (its words checked before the port is opened, its plan checked from where the
stage is before it moves, then planned again as it is sent), so memory does not grow with it.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

import click
import serial

from emulator.cli.common import fail
from emulator.tools.progress import Progress
from emulator.tools.readers import LineReader, ReadError, empty_error, open_regular
from protocols.clients import MS2000
from protocols.clients.gcode import (
    ExecutionError,
    GcodeError,
    GcodeExecutor,
    Step,
    iter_blocks,
    iter_program,
    moving_axes,
)

WHAT = "G-code program"
#: the longest program line read (bytes): a G-code line is tens of characters
MAX_LINE = 64 << 10

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
@click.argument("file", type=click.Path(path_type=Path))
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
    from the stage's zero; the program starts where the stage is. A program of any length is read
    a line at a time; on a terminal, stderr shows the lines read so far.

    Exit status: 0 when the program ran (or was planned) to its end; 1, with one line on stderr,
    when FILE is not a regular file, is empty, has a line it cannot read or run, or the controller
    refuses or falls silent; 2 for a bad option."""
    plan = partial(iter_program, xyz_scale=xyz_scale, speed_scale=speed_scale)
    try:
        if dry_run:
            with Progress(f"stage-emu gcode: planning {file}", enabled=not sys.stdout.isatty()) as progress:
                _print_plan(plan(_lines(file, progress)))
            return
        if port is None:
            fail("--port PATH is required (or --dry-run to only plan)")
        for _ in iter_blocks(_lines(file)):  # a malformed line is reported before the port is opened
            pass
        _run(file, str(port), int(baud), timeout, plan, verbose)
    except ReadError as exc:
        fail(str(exc))
    except GcodeError as exc:
        fail(f"{file}:{exc.line}: {exc.message}")
    except ExecutionError as exc:
        fail(f"{file}:{exc.line}: {exc.message}" if exc.line is not None else f"{port}: {exc.message}")
    except KeyboardInterrupt:
        fail(
            "interrupted"
            if dry_run
            else "interrupted: a running program was halted and its TTL output switched off"
        )


def _lines(file: Path, progress: Progress | None = None) -> Iterator[str]:
    """The program's lines as text, read as they are needed; ReadError for a file that is not a
    regular one, a line too long or not UTF-8, and a file without a single non-blank line."""
    found = False
    with open_regular(file, WHAT) as opened:
        for number, data in LineReader(opened, file, WHAT, max_line=MAX_LINE, keep_last=True):
            if progress is not None:
                progress.tick()
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                raise ReadError(f"{file}:{number}: not a {WHAT}: not UTF-8 text") from None
            found = found or bool(text.strip())
            yield text
    if not found:
        raise empty_error(file, WHAT)


def _print_plan(steps: Iterator[Step]) -> None:
    write = sys.stdout.write
    for step in steps:
        write(f"{step}\n")
    sys.stdout.flush()


def _run(
    file: Path, port: str, baud: int, timeout: float, plan: Callable[..., Iterator[Step]], verbose: bool
) -> None:
    try:
        stage = MS2000(port, baud, timeout)
    except (serial.SerialException, OSError) as exc:
        fail(f"{port}: cannot open the port: {exc}")
    with stage:
        executor = GcodeExecutor(stage)
        counts = executor.counts_per_mm()
        click.echo("counts per mm: " + " ".join(f"{a}={c:g}" for a, c in counts.items()))
        start = executor.start_position()
        axes = moving_axes(plan(_lines(file), start=start))  # the whole plan checked before a move
        with Progress(f"stage-emu gcode: running {file}", enabled=not verbose) as progress:

            def show(step: Step) -> None:
                if verbose:
                    click.echo(str(step))

            summary = executor.run(plan(_lines(file, progress), start=start), show, axes=axes)
    click.echo(
        f"done: {summary.moves} moves, {summary.dwells} dwells, {summary.outputs} output changes "
        f"in {summary.seconds:.1f} s"
    )
