"""The figure of `stage-emu plot`: a session (emulator/tools/plot.py) drawn with matplotlib.

Imported only by the plot command, after it has chosen the Agg backend: matplotlib is an optional
extra (`stage-emu[plot]`). The main panel is the path in a plane (or in 3-D), OUT0 high (a TRACER
laser on) solid and low dashed, ARRAY cells numbered in arrival order, SCAN sync and line-end marks;
below it the third axis over time when that axis moved.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from emulator.tools.plot import Session

#: `--axes`: the axes of the main panel
VIEWS = {"xy": ("X", "Y"), "xz": ("X", "Z"), "yz": ("Y", "Z"), "xyz": ("X", "Y", "Z")}
#: at this extent (µm) and beyond, positions are shown in mm
MM_FROM_UM = 1000.0
#: more SCAN lines than this and their pixel counts are not written beside the marks
LABELLED_LINES = 24
PATH_COLOUR = "tab:blue"
OFF_COLOUR = "0.55"


@dataclass(frozen=True)
class Unit:
    name: str
    per_um: float


@dataclass(frozen=True)
class Run:
    """A stretch of the path with one line style: OUT0 high (True), low (False) or unknown (None)."""

    laser: bool | None
    points: list[tuple[float, ...]]


def unit_for(values: Sequence[float]) -> Unit:
    extent = max(values) - min(values) if values else 0.0
    return Unit("mm", 0.001) if extent >= MM_FROM_UM else Unit("µm", 1.0)


def path_runs(session: Session, axes: Sequence[str], times: Sequence[float]) -> list[Run]:
    """The path through `times` split where OUT0 changes; each run starts where the last ended."""
    points = [tuple(session.at(a, t) for a in axes) for t in times]
    runs: list[Run] = []
    for (t0, here), (t1, there) in itertools.pairwise(zip(times, points, strict=True)):
        laser = session.laser_on((t0 + t1) / 2)
        if runs and runs[-1].laser == laser:
            runs[-1].points.append(there)
        else:
            runs.append(Run(laser, [here, there]))
    if not runs:  # a session of one instant: the stage stands still
        runs.append(Run(session.laser_on(times[0]), [points[0], points[0]]))
    return runs


def draw(session: Session, view: str, output: Path, title: str | None = None) -> None:
    """Draw `session` in `view` (a VIEWS key) to `output` (.png or .svg). Raises OSError when the
    file cannot be written."""
    axes = VIEWS[view]
    times = session.sample_times()
    runs = path_runs(session, axes, times)
    unit = unit_for([x for run in runs for point in run.points for x in point])
    others = [a for a in ("Z", "Y", "X") if a not in axes and session.moved(a)][:1]
    figure = Figure(figsize=(7.2, 7.6 if others else 6.2), layout="constrained")
    grid = figure.add_gridspec(2 if others else 1, 1, height_ratios=[3.2, 1] if others else [1])
    if len(axes) == 3:
        panel = figure.add_subplot(grid[0], projection="3d")
    else:
        panel = figure.add_subplot(grid[0])
        panel.set_aspect("equal", adjustable="datalim")
    _draw_path(panel, runs, unit)
    _draw_marks(panel, session, axes, unit)
    for i, axis in enumerate(axes):
        getattr(panel, f"set_{'xyz'[i]}label")(f"{axis} ({unit.name})")
    span = f"{session.start:.2f}–{session.end:.2f} s device time"
    panel.set_title(title or f"{session.device}: {'-'.join(axes)} path, {span}")
    panel.grid(True, alpha=0.3)
    panel.legend(loc="best", fontsize="small", framealpha=0.85)
    if others:
        _draw_over_time(figure.add_subplot(grid[1]), session, others[0], times)
    kind = output.suffix.lower().lstrip(".")
    figure.savefig(output, format=kind, dpi=100)


def _draw_path(panel: Any, runs: list[Run], unit: Unit) -> None:
    styles = {
        None: {"color": PATH_COLOUR, "linestyle": "-", "linewidth": 1.4, "label": "path"},
        True: {"color": PATH_COLOUR, "linestyle": "-", "linewidth": 1.8, "label": "laser on (OUT0 high)"},
        False: {"color": OFF_COLOUR, "linestyle": "--", "linewidth": 1.0, "label": "laser off (OUT0 low)"},
    }
    labelled: set[bool | None] = set()
    for run in runs:
        style = dict(styles[run.laser])
        if run.laser in labelled:
            style.pop("label")
        labelled.add(run.laser)
        columns = [[x * unit.per_um for x in column] for column in zip(*run.points, strict=True)]
        panel.plot(*columns, **style)
    # a ring round the start (and round an ARRAY cell's number there), a dot at the end under any
    # cell's number: both show when the path ends where it began
    ends = (
        (runs[0].points[0], {"markersize": 17, "markerfacecolor": "none", "label": "start", "zorder": 5}),
        (runs[-1].points[-1], {"markersize": 6, "label": "end", "zorder": 2.5}),
    )
    for (point, style), colour in zip(ends, ("tab:green", "tab:red"), strict=True):
        columns = [[x * unit.per_um] for x in point]
        panel.plot(*columns, marker="o", color=colour, markeredgewidth=2, linestyle="", **style)


def _draw_marks(panel: Any, session: Session, axes: Sequence[str], unit: Unit) -> None:
    def where(t: float) -> list[float]:
        return [session.at(a, t) * unit.per_um for a in axes]

    flat = len(axes) == 2
    for n, arrival in enumerate(session.arrivals):
        point = where(arrival.t)
        label = "ARRAY cell (arrival order)" if n == 0 else None
        panel.plot(
            *[[x] for x in point],
            marker="o",
            markersize=13,
            color="white",
            markeredgecolor="black",
            linestyle="",
            label=label,
            zorder=3,
        )
        text = str(arrival.number)
        if flat:
            panel.annotate(text, point, ha="center", va="center", fontsize=8, weight="bold", zorder=4)
        else:
            panel.text(*point, text, ha="center", va="center", fontsize=8, weight="bold")
    syncs = [m for m in session.scan_marks if m.pixels is None]
    ends = [m for m in session.scan_marks if m.pixels is not None]
    for marks, marker, colour, label in (
        (syncs, ">", "tab:orange", "SCAN sync (active region starts)"),
        (ends, "x", "tab:purple", "SCAN line end (pixel count)"),
    ):
        if not marks:
            continue
        columns = list(zip(*(where(m.t) for m in marks), strict=True))
        panel.plot(*columns, marker=marker, color=colour, linestyle="", markersize=7, label=label, zorder=3)
    if flat and len(ends) <= LABELLED_LINES:
        for mark in ends:
            panel.annotate(
                f"{mark.pixels}",
                where(mark.t),
                textcoords="offset points",
                xytext=(5, 3),
                fontsize=7,
                color="tab:purple",
            )


def _draw_over_time(panel: Axes, session: Session, axis: str, times: Sequence[float]) -> None:
    values = [session.at(axis, t) for t in times]
    unit = unit_for(values)
    panel.plot(times, [v * unit.per_um for v in values], color=PATH_COLOUR, linewidth=1.2)
    panel.set_xlabel("device time (s)")
    panel.set_ylabel(f"{axis} ({unit.name})")
    panel.set_title(f"{axis} over time", fontsize="medium")
    panel.grid(True, alpha=0.3)
