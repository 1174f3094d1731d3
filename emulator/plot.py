"""A session read back from a traffic log (emulator/trafficlog.py) for `stage-emu plot`: where each
axis was over time, from the device's own `move` records, and what happened on the way.

Pure (no matplotlib): `read_session` gives a `Session` whose `Track`s interpolate an axis's position
at any device time, linearly between the knots of its latest `move` record (a later record
supersedes an earlier one from its first knot on), and whose event lists hold ARRAY arrivals, SCAN
sync and pixel-count marks and OUT0 (laser) edges. `sample_times` lists the instants between which
every path is a straight line, so a polyline through them is the path itself.
"""

from __future__ import annotations

import bisect
import itertools
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from emulator.trace import parse_record
from emulator.trafficlog import MOVE


class LogError(Exception):
    """A traffic log that cannot be plotted; the message is one line naming the file."""


@dataclass(frozen=True)
class Leg:
    """One `move` record for one axis: knots (device time, µm) and the speed after the last one."""

    knots: tuple[tuple[float, float], ...]
    cruise: float = 0.0

    @property
    def start(self) -> float:
        return self.knots[0][0]

    @cached_property
    def times(self) -> list[float]:
        return [t for t, _ in self.knots]

    def at(self, t: float) -> float:
        i = bisect.bisect_right(self.times, t)
        if i == 0:
            return self.knots[0][1]
        if i == len(self.knots):
            last_t, last_x = self.knots[-1]
            return last_x + self.cruise * (t - last_t)
        (t0, x0), (t1, x1) = self.knots[i - 1], self.knots[i]
        return x0 + (x1 - x0) * (t - t0) / (t1 - t0)


@dataclass(frozen=True)
class Track:
    """One axis's legs in device-time order (at least one)."""

    legs: tuple[Leg, ...]

    @cached_property
    def starts(self) -> list[float]:
        return [leg.start for leg in self.legs]

    def at(self, t: float) -> float:
        """The position (µm) at `t`: before the first leg the axis rests where that leg starts."""
        i = bisect.bisect_right(self.starts, t)
        return self.legs[max(i - 1, 0)].at(t)

    def times(self) -> list[float]:
        """Knot times that are not superseded by a later leg."""
        out: list[float] = []
        for leg, after in zip(self.legs, [*self.legs[1:], None], strict=True):
            end = math.inf if after is None else after.start
            out.extend(t for t, _ in leg.knots if t < end)
        return out

    def moved(self) -> bool:
        positions = {x for leg in self.legs for _, x in leg.knots}
        return len(positions) > 1 or any(leg.cruise for leg in self.legs)


@dataclass(frozen=True)
class Arrival:
    """An ARRAY cell reached (`array_arrival`): `number` counts arrivals from 1."""

    t: float
    number: int
    i: int
    j: int


@dataclass(frozen=True)
class ScanMark:
    """`scan_sync` (pixels None) or `scan_pixels` (the line's pixel count) of a SCAN line."""

    t: float
    line: int
    pixels: int | None = None


@dataclass
class Session:
    device: str
    tracks: dict[str, Track]
    start: float
    end: float
    arrivals: list[Arrival] = field(default_factory=list)
    scan_marks: list[ScanMark] = field(default_factory=list)
    #: OUT0 edges (`ttl_out0`): (device time, level)
    laser: list[tuple[float, int]] = field(default_factory=list)

    def at(self, axis: str, t: float) -> float:
        """An axis's position (µm); an axis without a `move` record is taken to stand at 0."""
        track = self.tracks.get(axis)
        return 0.0 if track is None else track.at(t)

    def moved(self, axis: str) -> bool:
        track = self.tracks.get(axis)
        return track is not None and track.moved()

    def laser_on(self, t: float) -> bool | None:
        """OUT0's level at `t`; None when the log has no OUT0 edge. Before the first edge the level
        is the opposite of that edge's."""
        if not self.laser:
            return None
        i = bisect.bisect_right([edge for edge, _ in self.laser], t)
        return bool(self.laser[i - 1][1]) if i else not self.laser[0][1]

    def sample_times(self) -> list[float]:
        """Every knot and OUT0 edge time, the session's start and end, in order, once each."""
        times = {self.start, self.end}
        for track in self.tracks.values():
            times.update(track.times())
        times.update(t for t, _ in self.laser)
        return sorted(t for t in times if self.start <= t <= self.end)


def read_records(path: Path) -> list[dict[str, Any]]:
    """The log's records; a last line cut short (the daemon stopped mid-write) is left out."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise LogError(f"{path}: does not exist") from None
    except IsADirectoryError:
        raise LogError(f"{path}: is a directory, not a traffic log") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LogError(f"{path}: cannot read it: {exc}") from None
    lines = text.splitlines()
    records: list[dict[str, Any]] = []
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines) and not text.endswith("\n"):
                break
            raise LogError(f"{path}:{number}: not a traffic log (not a JSON record)") from None
        try:
            parse_record(line)  # the one check of a record's form, shared with `stage-emu trace`
        except ValueError as exc:
            raise LogError(f"{path}:{number}: not a traffic log record ({exc})") from None
        records.append(record)
    if not records:
        raise LogError(f"{path}: empty, no traffic log records")
    return records


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def read_session(path: Path, device: str | None = None) -> Session:
    """The session of `device` (default: the only device with `move` records) in the log at `path`."""
    return session_from(path, read_records(path), device)


def session_from(path: Path, records: list[dict[str, Any]], device: str | None = None) -> Session:
    """`read_session` of the records read from `path`."""
    devices = sorted({r["device"] for r in records})
    if device is not None and device not in devices:
        raise LogError(f"{path}: no device {device!r} (the log holds: {', '.join(devices)})")
    moving = sorted({r["device"] for r in records if r.get("ev") == MOVE})
    if device is None:
        if not moving:
            raise LogError(f"{path}: no move records: was it written by `stage-emu serve --log-traffic`?")
        if len(moving) > 1:
            several = ", ".join(moving)
            raise LogError(f"{path}: moves of several devices ({several}): choose one with --device")
        device = moving[0]
    elif device not in moving:
        raise LogError(f"{path}: no move records of device {device!r}")
    return session_of(path, device, records)


def session_of(path: Path, device: str, records: list[dict[str, Any]]) -> Session:
    """`device`'s session from the records of the log at `path`; `Session.tracks` may be empty."""
    own = sorted((r for r in records if r["device"] == device), key=lambda r: r["t"])
    try:
        return _session(device, own)
    except (TypeError, ValueError, KeyError, IndexError) as exc:
        raise LogError(f"{path}: a malformed {device} event record ({exc})") from None


def _session(device: str, records: list[dict[str, Any]]) -> Session:
    legs: dict[str, list[Leg]] = {}
    session = Session(device, {}, records[0]["t"], records[-1]["t"])
    for record in records:
        if record["dir"] != "ev":
            continue
        ev, t = record.get("ev"), record["t"]
        if ev == MOVE:
            for axis, leg in _legs(record):
                legs.setdefault(axis, []).append(leg)
        elif ev == "array_arrival":
            session.arrivals.append(Arrival(t, len(session.arrivals) + 1, int(record["i"]), int(record["j"])))
        elif ev == "scan_sync":
            session.scan_marks.append(ScanMark(t, int(record["line"])))
        elif ev == "scan_pixels":
            session.scan_marks.append(ScanMark(t, int(record["line"]), int(record["count"])))
        elif ev == "ttl_out0":
            session.laser.append((t, int(record["level"])))
    # a stable sort: records of one instant keep their order, the last one standing
    session.tracks = {axis: Track(tuple(sorted(own, key=_start))) for axis, own in legs.items()}
    session.start = min([session.start, *(track.legs[0].start for track in session.tracks.values())])
    return session


def _start(leg: Leg) -> float:
    return leg.start


def _legs(record: dict[str, Any]) -> Iterable[tuple[str, Leg]]:
    cruise = record.get("cruise") or {}
    for axis, knots in record["path"].items():
        points = tuple((float(t), float(x)) for t, x in knots)
        if not points or not all(math.isfinite(t) and math.isfinite(x) for t, x in points):
            raise ValueError(f"axis {axis}: no finite knots")
        if any(b[0] < a[0] for a, b in itertools.pairwise(points)):
            raise ValueError(f"axis {axis}: knots out of time order")
        yield str(axis), Leg(points, float(cruise.get(axis, 0.0)))
