"""A CRISP or AUTOFOCUS session read back from a traffic log for `stage-emu plot`'s focus figure
(emulator/plot_focus_figure.py draws it).

Pure (no matplotlib). `read_focus` gives a `Focus`: the session (emulator/plot.py) whose focus-axis
track comes from the `move` records; CRISP's state changes (`crisp` events, each with the in-focus
band), its focus error and the surface's place (each state change's reading and, while the log was
kept, each lock-loop update's `crisp_sample`); AUTOFOCUS's runs (`af_start`, `af_end` with its
result) and the focus value of each video frame scanned (`af_sample`).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from emulator.plot import LogError, Session, read_records, session_of
from emulator.trafficlog import AF_SAMPLE, CRISP_SAMPLE, MOVE

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


def focus_device(records: list[dict[str, Any]], device: str | None) -> str | None:
    """The device `stage-emu plot` draws a focus figure of without being told: `device` (else the
    log's only device with move or focus records) when it has CRISP or AUTOFOCUS records."""
    if device is None:
        drawn = {r["device"] for r in records if r.get("ev") == MOVE or r.get("ev") in FOCUS_EVENTS}
        if len(drawn) != 1:
            return None
        device = drawn.pop()
    return device if any(r["device"] == device and r.get("ev") in FOCUS_EVENTS for r in records) else None


def read_focus(path: Path, device: str | None = None) -> Focus:
    """The focus session of `device` (default: the only device with focus records) in the log."""
    return focus_of(path, read_records(path), device)


def focus_of(path: Path, records: list[dict[str, Any]], device: str | None = None) -> Focus:
    devices = sorted({r["device"] for r in records})
    if device is not None and device not in devices:
        raise LogError(f"{path}: no device {device!r} (the log holds: {', '.join(devices)})")
    focusing = sorted({r["device"] for r in records if r.get("ev") in FOCUS_EVENTS})
    if device is None:
        if not focusing:
            raise LogError(f"{path}: no CRISP or AUTOFOCUS records: was the device served with either?")
        if len(focusing) > 1:
            several = ", ".join(focusing)
            raise LogError(f"{path}: focus records of several devices ({several}): choose one with --device")
        device = focusing[0]
    elif device not in focusing:
        raise LogError(f"{path}: no CRISP or AUTOFOCUS records of device {device!r}")
    focus = Focus(session_of(path, device, records))
    own = sorted((r for r in records if r["device"] == device and r.get("ev") in FOCUS_EVENTS), key=_time)
    try:
        for record in own:
            _read(focus, record)
    except (TypeError, ValueError, KeyError) as exc:
        raise LogError(f"{path}: a malformed {device} focus record ({exc})") from None
    return focus


def _time(record: dict[str, Any]) -> float:
    return float(record["t"])


def _read(focus: Focus, record: dict[str, Any]) -> None:
    ev, t = record["ev"], float(record["t"])
    if record.get("axis"):
        focus.axis = str(record["axis"])
    if ev in (CRISP_STATE, CRISP_SAMPLE):
        focus.readings.append(Reading(t, float(record["error"]), float(record["surface_um"])))
    if ev == CRISP_STATE:
        focus.states.append(StateChange(t, str(record["state"]), float(record["in_focus_counts"])))
    elif ev == AF_START:
        focus.runs.append(AfRun(t, bool(record["calibrating"])))
    elif ev == AF_END:
        peak, peak_um = record.get("peak"), record.get("peak_um")
        run = (
            focus.runs.pop()
            if focus.runs and focus.runs[-1].end is None
            else AfRun(focus.session.start, False)
        )
        focus.runs.append(
            AfRun(
                run.start,
                bool(record["calibrating"]),
                t,
                str(record["result"]),
                None if peak is None else float(peak),
                None if peak_um is None else float(peak_um),
            )
        )
    elif ev == AF_SAMPLE:
        filtered = record.get("filtered")
        value = float(record["value"])
        focus.samples.append(
            AfSample(t, float(record["z_um"]), value, None if filtered is None else float(filtered))
        )
