"""`stage-emu plot TRAFFIC_LOG -o path.svg|png`: the path of a served session, drawn from the device's
own `move` records in a `--log-traffic` file (emulator/tools/plot.py reads it, emulator/tools/plot_figure.py
draws it), or for a CRISP or AUTOFOCUS session its focus over time (emulator/tools/plot_focus.py,
emulator/tools/plot_focus_figure.py). The log is read in one pass and bounded memory
(emulator/tools/plot_scan.py) before matplotlib, an optional extra, is imported, and only to draw; every
failure is one line, exit 1.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import click

from emulator.cli.common import fail
from emulator.tools.plot_focus import Focus
from emulator.tools.plot_scan import focus_device, focus_of, read_log, session_from
from emulator.tools.progress import Progress
from emulator.tools.readers import ReadError

NEEDS_MATPLOTLIB = "stage-emu plot needs matplotlib: pip install 'stage-emu[plot]'"
FORMATS = (".png", ".svg")
VIEW_NAMES = ("xy", "xz", "yz", "xyz")


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
@click.option(
    "--focus/--path",
    "focus",
    default=None,
    help="The focus figure (CRISP, AUTOFOCUS) or the stage's path [default: focus when the device has "
    "CRISP or AUTOFOCUS records].",
)
@click.option("--title", help="The figure's title (default: device, axes and time span).")
def plot(
    traffic_log: Path, output: Path, device: str | None, view: str, focus: bool | None, title: str | None
) -> None:
    """Draw the path a device's stage took in TRAFFIC_LOG (written by `stage-emu serve --log-traffic`).

    Positions come from the device's own move records, in µm or mm of its user coordinates. ARRAY
    cells are numbered in arrival order, SCAN sync and line ends are marked, and OUT0 (a TRACER
    laser) high is drawn solid, low dashed. The third axis is drawn over time below when it moved.

    A CRISP or AUTOFOCUS session is drawn over time instead: the focus axis (with CRISP's surface),
    the focus error and its in-focus band (or AUTOFOCUS's focus value), CRISP's states and
    AUTOFOCUS's runs.

    A long log is thinned to a few thousand points per series (the first, last, lowest and highest
    of each stretch of time), so the path keeps its extent and shape. On a terminal, stderr shows
    the lines read so far.

    Exit status: 0 when the figure is written; 1, with one line on stderr, when TRAFFIC_LOG is not
    a regular file, is empty or no traffic log (a line too long or nested too deep included), holds
    nothing to draw, or the figure cannot be written."""
    if output.suffix.lower() not in FORMATS:
        fail(f"{output}: the output must end in .png or .svg")
    if _missing("matplotlib"):
        click.echo(NEEDS_MATPLOTLIB, err=True)
        sys.exit(1)
    try:
        with Progress(f"stage-emu plot: reading {traffic_log}") as progress:
            scan = read_log(traffic_log, progress.tick)
        wanted = focus if focus is not None else focus_device(scan, device) is not None
        drawn = focus_of(traffic_log, scan, device) if wanted else session_from(traffic_log, scan, device)
    except ReadError as exc:
        fail(str(exc))
    import matplotlib

    matplotlib.use("Agg")
    from emulator.tools.plot_figure import draw
    from emulator.tools.plot_focus_figure import draw_focus

    session = drawn.session if isinstance(drawn, Focus) else drawn
    try:
        if isinstance(drawn, Focus):
            draw_focus(drawn, output, title)
        else:
            draw(drawn, view, output, title)
    except OSError as exc:
        fail(f"{output}: cannot write it: {exc.strerror or exc}")
    click.echo(f"{output}: {session.device}, {session.end - session.start:.2f} s of device time")


def _missing(module: str) -> bool:
    """Whether `module` cannot be imported (looked up, not imported: matplotlib takes a while)."""
    try:
        return importlib.util.find_spec(module) is None
    except (ImportError, ValueError):  # a module set to None in sys.modules, or a broken install
        return True
