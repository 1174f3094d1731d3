"""`stage-emu plot TRAFFIC_LOG -o path.svg|png`: the path of a served session, drawn from the device's
own `move` records in a `--log-traffic` file (emulator/plot.py reads it, emulator/plot_figure.py draws
it). matplotlib is an optional extra, imported only here; every failure is one line, exit 1.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import NoReturn

import click

from emulator.plot import LogError, read_session

NEEDS_MATPLOTLIB = "stage-emu plot needs matplotlib: pip install 'stage-emu[plot]'"
FORMATS = (".png", ".svg")
VIEW_NAMES = ("xy", "xz", "yz", "xyz")


def _fail(message: str) -> NoReturn:
    click.echo(f"stage-emu: {message}", err=True)
    sys.exit(1)


@click.command("plot")
@click.argument("traffic_log", type=click.Path(path_type=Path))
@click.option(
    "-o", "--output", required=True, type=click.Path(path_type=Path), help="The figure: a .png or .svg file."
)
@click.option("--device", metavar="NAME", help="The device to draw when the log holds several.")
@click.option(
    "--axes",
    "view",
    type=click.Choice(VIEW_NAMES),
    default="xy",
    show_default=True,
    help="The plane of the path (xyz: in 3-D).",
)
@click.option("--title", help="The figure's title (default: device, axes and time span).")
def plot(traffic_log: Path, output: Path, device: str | None, view: str, title: str | None) -> None:
    """Draw the path a device's stage took in TRAFFIC_LOG (written by `stage-emu serve --log-traffic`).

    Positions come from the device's own move records, in µm or mm of its user coordinates. ARRAY
    cells are numbered in arrival order, SCAN sync and line ends are marked, and OUT0 (a TRACER
    laser) high is drawn solid, low dashed. The third axis is drawn over time below when it moved."""
    if output.suffix.lower() not in FORMATS:
        _fail(f"{output}: the output must end in .png or .svg")
    try:
        import matplotlib
    except ImportError:
        click.echo(NEEDS_MATPLOTLIB, err=True)
        sys.exit(1)
    matplotlib.use("Agg")
    from emulator.plot_figure import draw

    try:
        session = read_session(traffic_log, device)
    except LogError as exc:
        _fail(str(exc))
    try:
        draw(session, view, output, title)
    except OSError as exc:
        _fail(f"{output}: cannot write it: {exc.strerror or exc}")
    click.echo(f"{output}: {session.device}, {session.end - session.start:.2f} s of device time")
