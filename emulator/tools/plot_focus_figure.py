"""The focus figure of `stage-emu plot`: a CRISP or AUTOFOCUS session (emulator/tools/plot_focus.py) drawn
over device time with matplotlib, panels sharing the time axis.

- the focus axis (µm), with the surface CRISP locks to and the peaks AUTOFOCUS found;
- CRISP's focus error (counts) with the in-focus band (`AL Z` × 1000 × G) shaded;
- AUTOFOCUS's focus value per video frame and its three-frame mean;
- CRISP's state characters as a track, one row per state entered;
- AUTOFOCUS's runs as bars, coloured and labelled by their result.

Imported only by the plot command after it has chosen the Agg backend (matplotlib is optional).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from emulator.tools.plot_focus import AfRun, Focus

Z_COLOUR, SURFACE_COLOUR, ERROR_COLOUR, BAND_COLOUR = "tab:blue", "tab:orange", "tab:red", "tab:green"
#: CRISP's state characters (MS-CRISP-1) as the state track names and colours them
STATE_NAMES = {
    "I": "idle",
    "R": "ready",
    "D": "dim",
    "K": "locked, not in focus",
    "F": "in focus",
    "N": "inhibited by a move",
    "E": "lock lost",
    "G": "log-amp calibrated",
    "f": "dither",
    "C": "gain calibration",
    "H": "log-amp calibration",
    "o": "offset reset",
    "l": "offset reset ending",
}
STATE_COLOURS = {"I": "0.7", "R": "tab:blue", "D": "0.4", "K": "tab:orange", "F": "tab:green"}
STATE_COLOURS |= {"N": "tab:purple", "E": "tab:red"}
OTHER_STATE_COLOUR = "tab:gray"
#: AUTOFOCUS run results (`af_end`) and their colours; None: the log ended during the run
RESULT_COLOURS = {"focused": "tab:green", "calibrated": "tab:blue", "no_contrast": "tab:red"}
STOPPED_COLOUR, RUNNING_COLOUR = "0.55", "0.8"
#: an error beyond this many in-focus bands puts the error axis on a symmetric log scale
LINEAR_BANDS = 8
#: a bar narrower than this share of the time span gets no text
LABELLED_SHARE = 0.06


def draw_focus(focus: Focus, output: Path, title: str | None = None) -> None:
    """Draw `focus` to `output` (.png or .svg). Raises OSError when the file cannot be written."""
    panels: list[tuple[float, Callable[[Axes, Focus], None]]] = [(2.2, _draw_z)]
    if focus.crisp:
        panels.append((2.0, _draw_error))
    if focus.autofocus:
        panels.append((2.0, _draw_value))
    if focus.states:
        rows = len({change.state for change in focus.states})
        panels.append((0.5 + 0.28 * rows, _draw_states))
    if focus.runs:
        panels.append((0.9, _draw_runs))
    heights = [height for height, _ in panels]
    figure = Figure(figsize=(8.0, 1.2 + sum(heights)), layout="constrained")
    grid = figure.add_gridspec(len(panels), 1, height_ratios=heights)
    first: Axes | None = None
    for i, (_, draw_panel) in enumerate(panels):
        panel = figure.add_subplot(grid[i], sharex=first)
        first = first or panel
        draw_panel(panel, focus)
        panel.grid(True, alpha=0.3)
        if i < len(panels) - 1:
            panel.tick_params(labelbottom=False)
    assert first is not None
    session = focus.session
    first.set_xlim(session.start, session.end)
    panel.set_xlabel("device time (s)")
    modules = " and ".join(
        name for name, on in (("CRISP", focus.crisp), ("AUTOFOCUS", focus.autofocus)) if on
    )
    span = f"{session.start:.2f}–{session.end:.2f} s device time"
    figure.suptitle(title or f"{session.device}: {modules} focus, {span}")
    figure.savefig(output, format=output.suffix.lower().lstrip("."), dpi=100)


def _draw_z(panel: Axes, focus: Focus) -> None:
    times = focus.z_times()
    panel.plot(
        times, [focus.z_um(t) for t in times], color=Z_COLOUR, linewidth=1.4, label=f"{focus.axis} axis"
    )
    if focus.readings:
        surface = [(r.t, r.surface_um) for r in focus.readings]
        panel.plot(
            *zip(*surface, strict=True), color=SURFACE_COLOUR, linestyle="--", linewidth=1.2, label="surface"
        )
    peaks = [(run.end, run.peak_um) for run in focus.runs if run.result == "focused" and run.end is not None]
    if peaks:
        panel.plot(*zip(*peaks, strict=True), "v", color=BAND_COLOUR, markersize=8, label="peak found (AF)")
    panel.set_ylabel(f"{focus.axis} (µm)")
    panel.set_title("focus axis", fontsize="medium", loc="left")
    panel.legend(loc="best", fontsize="small", framealpha=0.85)


def _draw_error(panel: Axes, focus: Focus) -> None:
    if focus.states:
        times = [change.t for change in focus.states] + [focus.session.end]
        bands = [change.in_focus_counts for change in focus.states]
        bands.append(bands[-1])
        below = [-band for band in bands]
        panel.fill_between(
            times, below, bands, step="post", color=BAND_COLOUR, alpha=0.2, label="in-focus band"
        )
    errors = [(r.t, r.error) for r in focus.readings]
    panel.plot(*zip(*errors, strict=True), color=ERROR_COLOUR, linewidth=1.0, label="focus error")
    panel.axhline(0.0, color="0.3", linewidth=0.6)
    band = max((change.in_focus_counts for change in focus.states), default=0.0)
    if band and max(abs(error) for _, error in errors) > LINEAR_BANDS * band:
        # a step or a move's error would flatten the band and the lock's small residue: linear near
        # zero, logarithmic beyond
        panel.set_yscale("symlog", linthresh=LINEAR_BANDS * band / 2, linscale=2.0)
        panel.set_ylabel("error (counts, symlog)")
    else:
        panel.set_ylabel("error (counts)")
    panel.set_title("CRISP focus error", fontsize="medium", loc="left")
    panel.legend(loc="best", fontsize="small", framealpha=0.85)


def _draw_value(panel: Axes, focus: Focus) -> None:
    samples = focus.samples
    if samples:
        panel.plot(
            [s.t for s in samples], [s.value for s in samples], ".", color="0.5", markersize=3, label="frame"
        )
        filtered = [(s.t, s.filtered) for s in samples if s.filtered is not None]
        if filtered:
            panel.plot(*zip(*filtered, strict=True), color=Z_COLOUR, linewidth=1.2, label="3-frame mean")
    peaks = [(_peak_time(focus, run), run.peak) for run in focus.runs if run.peak is not None]
    if peaks:
        panel.plot(*zip(*peaks, strict=True), "v", color=BAND_COLOUR, markersize=8, label="run's peak")
    panel.set_ylabel("focus value")
    panel.set_title("AUTOFOCUS focus value", fontsize="medium", loc="left")
    if samples or peaks:
        panel.legend(loc="best", fontsize="small", framealpha=0.85)


def _peak_time(focus: Focus, run: AfRun) -> float:
    """When the run met its peak: its sample of the highest three-frame mean, else its end."""
    end = focus.session.end if run.end is None else run.end
    met = [s for s in focus.samples if run.start <= s.t <= end and s.filtered is not None]
    return max(met, key=lambda s: s.filtered or 0.0).t if met else end


def _draw_states(panel: Axes, focus: Focus) -> None:
    order = list(dict.fromkeys(change.state for change in focus.states))
    ends = [change.t for change in focus.states[1:]] + [focus.session.end]
    for change, end in zip(focus.states, ends, strict=True):
        row = order.index(change.state)
        colour = STATE_COLOURS.get(change.state, OTHER_STATE_COLOUR)
        panel.broken_barh([(change.t, end - change.t)], (row - 0.35, 0.7), color=colour)
    panel.set_yticks(range(len(order)))
    panel.set_yticklabels([f"{s}  {STATE_NAMES.get(s, 'state ' + s)}" for s in order], fontsize="small")
    panel.set_ylim(len(order) - 0.5, -0.5)
    panel.set_title("CRISP state (LK X?)", fontsize="medium", loc="left")


def _draw_runs(panel: Axes, focus: Focus) -> None:
    span = focus.session.end - focus.session.start
    shown: dict[str, str] = {}
    for run in focus.runs:
        end = focus.session.end if run.end is None else run.end
        result = run.result or "running at the log's end"
        colour = RUNNING_COLOUR if run.result is None else RESULT_COLOURS.get(result, STOPPED_COLOUR)
        hatch = "//" if run.calibrating else None
        panel.broken_barh(
            [(run.start, end - run.start)], (0.2, 0.6), color=colour, hatch=hatch, edgecolor="0.2"
        )
        shown.setdefault(result, colour)
        if end - run.start >= LABELLED_SHARE * span:
            panel.text((run.start + end) / 2, 0.5, result, ha="center", va="center", fontsize="small")
    panel.set_yticks([])
    panel.set_ylim(0, 1)
    panel.set_title("AUTOFOCUS runs (hatched: calibration)", fontsize="medium", loc="left")
    handles = [Patch(color=colour, label=result) for result, colour in shown.items()]
    # above the bars, right of the title: the bars carry their own text
    panel.legend(
        handles=handles,
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        fontsize="small",
        frameon=False,
        ncols=len(handles),
    )
