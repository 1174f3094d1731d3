"""`stage-emu trace TRAFFIC_LOG [--follow]`: a `--log-traffic` file as readable exchanges, one line
each (emulator/tools/trace.py reads and pairs). Every failure is one line, exit 1: a file that is not
a regular file, a line too long or nested too deep, a file with no record (without --follow).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import click

from emulator.cli.common import fail
from emulator.tools.readers import ReadError
from emulator.tools.trace import EVENT_CHOICES, TraceNotes, TraceOptions, trace_lines


@contextmanager
def _stop_on_interrupt(stop: threading.Event) -> Iterator[None]:
    """Ctrl-C ends following cleanly: what is still waiting for a reply is printed, no traceback."""
    previous = signal.signal(signal.SIGINT, lambda _signum, _frame: stop.set())
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@click.command("trace")
@click.argument("traffic_log", type=click.Path(path_type=Path))
@click.option("-f", "--follow", is_flag=True, help="Keep reading as the log grows (Ctrl-C stops).")
@click.option("--device", metavar="NAME", help="Only this device's traffic and events.")
@click.option("--port", metavar="NAME", help="Only traffic on this port (e.g. main, aux).")
@click.option(
    "--events",
    type=click.Choice(EVENT_CHOICES),
    default="state",
    show_default=True,
    help="Device events to show: none, those that change its state (move_complete, ttl_out0, ...), "
    "or all, with the per-leg move records and lock-loop samples.",
)
def trace(traffic_log: Path, follow: bool, device: str | None, port: str | None, events: str) -> None:
    """Show TRAFFIC_LOG (written by `stage-emu serve --log-traffic`) as exchanges.

    One line per exchange: device time (s) and the host's time of day, device/port, the request as
    the device read it (its summary and bytes), the reply's bytes and what it says, and the latency
    from the request's last byte to the reply's last byte. Bytes the device garbled, never heard
    (LOST) or found outside any command (STRAY), unsolicited output and device events (`*`) get
    lines of their own.

    Exit status: 0 when the log was read to its end (or --follow was stopped with Ctrl-C); 1, with
    one line on stderr, when TRAFFIC_LOG is not a regular file, is not a traffic log, holds no record
    (without --follow, which waits for them), has a line too long or nested too deep, or a filter
    names nothing in it."""
    options = TraceOptions(device=device, port=port, events=events)
    notes = TraceNotes()
    stop = threading.Event()
    try:
        if follow:
            with _stop_on_interrupt(stop):
                _echo_all(traffic_log, options, follow, stop, notes)
        else:
            _echo_all(traffic_log, options, follow, stop, notes)
    except ReadError as exc:
        fail(str(exc))
    except KeyboardInterrupt:  # Ctrl-C while reading a long log without --follow
        sys.exit(130)
    except BrokenPipeError:
        # the reader went away (`| head`): stop quietly, and let the exit's flush go nowhere
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)
    if notes.malformed:
        click.echo(f"stage-emu: {traffic_log}: skipped {notes.malformed} malformed lines", err=True)
    if notes.incomplete_tail:
        click.echo(
            f"stage-emu: {traffic_log}: the last line is incomplete (still being written?); skipped", err=True
        )


def _echo_all(
    path: Path, options: TraceOptions, follow: bool, stop: threading.Event, notes: TraceNotes
) -> None:
    for line in trace_lines(path, options, follow=follow, stop=stop, notes=notes):
        click.echo(line)
