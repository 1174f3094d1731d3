"""A CRISP or AUTOFOCUS session read back from a traffic log for `stage-emu plot`'s focus figure
(emulator/tools/plot_focus_figure.py draws it).

Pure (no matplotlib). A `Focus` is the session (emulator/tools/plot.py) whose focus-axis track comes from
the `move` records; CRISP's state changes (`crisp` events, each with the in-focus band), its focus
error and the surface's place (each state change's reading and, while the log was kept, each
lock-loop update's `crisp_sample`); AUTOFOCUS's runs (`af_start`, `af_end` with its result) and the
focus value of each video frame scanned (`af_sample`). `FocusBuilder` gathers one record by record
(emulator/tools/plot_scan.py reads the log).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field, replace
from typing import Any

from emulator.device import AF_SAMPLE, CRISP_SAMPLE
from emulator.tools.decimate import Buckets, ends, extremes
from emulator.tools.plot import POINTS, Session

CRISP_STATE = "crisp"
AF_START, AF_END = "af_start", "af_end"
#: records that make a session a focus session
FOCUS_EVENTS = frozenset({CRISP_STATE, CRISP_SAMPLE, AF_START, AF_END, AF_SAMPLE})
#: the axis CRISP and AUTOFOCUS move unless an event names another (`UL F`, `AFC`)
DEFAULT_AXIS = "Z"


@dataclass(frozen=True)
class Reading:
    """CRISP's focus error (counts) and the surface's place (user µm of the focus axis) at `t`."""

    t: float
    error: float
    surface_um: float


@dataclass(frozen=True)
class StateChange:
    """CRISP entered `state` (a state character, MS-CRISP-1); `in_focus_counts` is the in-focus band
    (±counts of error) in force then."""

    t: float
    state: str
    in_focus_counts: float


@dataclass(frozen=True)
class AfRun:
    """One AUTOFOCUS run or calibration; `end` and `result` are None when the log ends first."""

    start: float
    calibrating: bool
    end: float | None = None
    result: str | None = None
    peak: float | None = None
    peak_um: float | None = None


@dataclass(frozen=True)
class AfSample:
    """The focus value of one video frame of a scan at `z_um`; `filtered` is the mean of the last
    three (None for a scan's first two frames)."""

    t: float
    z_um: float
    value: float
    filtered: float | None


@dataclass
class Focus:
    session: Session
    axis: str = DEFAULT_AXIS
    states: list[StateChange] = field(default_factory=list)
    readings: list[Reading] = field(default_factory=list)
    runs: list[AfRun] = field(default_factory=list)
    samples: list[AfSample] = field(default_factory=list)

    @property
    def crisp(self) -> bool:
        return bool(self.states or self.readings)

    @property
    def autofocus(self) -> bool:
        return bool(self.runs or self.samples)

    def z_um(self, t: float) -> float:
        return self.session.at(self.axis, t)

    def z_times(self) -> list[float]:
        """The focus axis's knot times and the session's ends: a polyline through them is its path."""
        track = self.session.tracks.get(self.axis)
        times = {self.session.start, self.session.end, *(track.times() if track else ())}
        return sorted(t for t in times if self.session.start <= t <= self.session.end)

    def state_at(self, t: float) -> StateChange | None:
        """The state CRISP was in at `t` (None before the first change the log saw)."""
        i = bisect.bisect_right([change.t for change in self.states], t)
        return self.states[i - 1] if i else None


class FocusBuilder:
    """A device's focus story gathered record by record in bounded memory: each list keeps at most
    `POINTS` items, a longer log thinned by time buckets (the samples and readings by min/max)."""

    def __init__(self) -> None:
        self.axis = DEFAULT_AXIS
        self._axis_t = -math.inf
        self.states: Buckets[StateChange] = Buckets(POINTS, ends)
        self.readings: Buckets[Reading] = Buckets(POINTS, extremes)
        self.runs: Buckets[AfRun] = Buckets(POINTS, ends)
        self.samples: Buckets[AfSample] = Buckets(POINTS, extremes)
        #: the run started and not yet ended
        self._open: AfRun | None = None
        #: ends whose start the log did not see: they start with the session
        self._headless: list[AfRun] = []

    def feed(self, record: dict[str, Any]) -> None:
        """One focus record of this device (`ev` in FOCUS_EVENTS)."""
        ev, t = record["ev"], float(record["t"])
        if record.get("axis") and t >= self._axis_t:  # the latest record naming an axis decides
            self.axis, self._axis_t = str(record["axis"]), t
        if ev in (CRISP_STATE, CRISP_SAMPLE):
            reading = Reading(t, float(record["error"]), float(record["surface_um"]))
            self.readings.add(t, reading, reading.error)
        if ev == CRISP_STATE:
            self.states.add(t, StateChange(t, str(record["state"]), float(record["in_focus_counts"])))
        elif ev == AF_START:
            if self._open is not None:
                self.runs.add(self._open.start, self._open)
            self._open = AfRun(t, bool(record["calibrating"]))
        elif ev == AF_END:
            peak, peak_um = record.get("peak"), record.get("peak_um")
            run = AfRun(
                math.nan if self._open is None else self._open.start,
                bool(record["calibrating"]),
                t,
                str(record["result"]),
                None if peak is None else float(peak),
                None if peak_um is None else float(peak_um),
            )
            self._open = None
            if math.isnan(run.start):
                self._headless.append(run)
            else:
                self.runs.add(run.start, run)
        elif ev == AF_SAMPLE:
            filtered = record.get("filtered")
            value = float(record["value"])
            sample = AfSample(t, float(record["z_um"]), value, None if filtered is None else float(filtered))
            self.samples.add(t, sample, value)

    def focus(self, session: Session) -> Focus:
        headless = [replace(run, start=session.start) for run in self._headless[:POINTS]]
        runs = sorted([*headless, *self.runs.items()], key=lambda run: run.start)
        if self._open is not None:
            runs.append(self._open)
        return Focus(
            session, self.axis, self.states.items(), self.readings.items(), runs, self.samples.items()
        )
