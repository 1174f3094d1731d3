"""A session read back from a traffic log (emulator/hosting/trafficlog.py) for `stage-emu plot`: where each
axis was over time, from the device's own `move` records, and what happened on the way.

Pure (no matplotlib): a `Session` has `Track`s that interpolate an axis's position at any device
time, linearly between the knots of its latest `move` record (a later record supersedes an earlier
one from its first knot on), and event lists of ARRAY arrivals, SCAN sync and pixel-count marks and
OUT0 (laser) edges. `sample_times` lists the instants between which every path is a straight line,
so a polyline through them is the path itself.

A `PathBuilder` gathers a session record by record (emulator/tools/plot_scan.py reads the log) in bounded
memory: an axis keeps at most `POINTS` knots and each event list as many; a longer log is thinned by
time buckets (emulator/tools/decimate.py) that keep each bucket's first, last, lowest and highest knots,
so the drawn path keeps its extent and its shape.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from emulator.hosting.trafficlog import MOVE
from emulator.tools.decimate import Buckets, ends, extremes
from emulator.tools.readers import ReadError


class LogError(ReadError):
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

    @cached_property
    def _laser_times(self) -> list[float]:
        return [edge for edge, _ in self.laser]

    def laser_on(self, t: float) -> bool | None:
        """OUT0's level at `t`; None when the log has no OUT0 edge. Before the first edge the level
        is the opposite of that edge's."""
        if not self.laser:
            return None
        i = bisect.bisect_right(self._laser_times, t)
        return bool(self.laser[i - 1][1]) if i else not self.laser[0][1]

    def sample_times(self) -> list[float]:
        """Every knot and OUT0 edge time, the session's start and end, in order, once each."""
        times = {self.start, self.end}
        for track in self.tracks.values():
            times.update(track.times())
        times.update(t for t, _ in self.laser)
        return sorted(t for t in times if self.start <= t <= self.end)


#: knots an axis keeps, and events of each kind: a long log is thinned to this (emulator/tools/decimate.py)
POINTS = 2000
#: the latest legs of an axis kept as they came (up to half its knots): a record written late (a
#: halt's, after its settle time) still finds the legs it supersedes or follows
RECENT_LEGS = 32


class TrackBuilder:
    """One axis's legs as the log gives them, in start order (a stable insertion: records of one
    instant keep their order, the last one standing). Past twice `limit` knots, all but the latest
    legs (at most `RECENT_LEGS`, with at most half of `limit` knots) are flattened into one leg
    (what the track says, knot by knot) thinned to min/max per time bucket: `limit` knots at most
    are left, and each thinning has twice as many knots to spare before the next."""

    def __init__(self, limit: int = POINTS) -> None:
        self.limit = limit
        self.legs: list[Leg] = []
        self._starts: list[float] = []
        self._knots = 0

    def add(self, leg: Leg) -> None:
        at = bisect.bisect_right(self._starts, leg.start)
        self.legs.insert(at, leg)
        self._starts.insert(at, leg.start)
        self._knots += len(leg.knots)
        if self._knots > 2 * self.limit:
            self._compact()

    def _compact(self) -> None:
        keep, knots = 0, 0
        for leg in reversed(self.legs[-RECENT_LEGS:]):
            if knots + len(leg.knots) > self.limit // 2:
                break
            keep, knots = keep + 1, knots + len(leg.knots)
        old, recent = self.legs[: len(self.legs) - keep], self.legs[len(self.legs) - keep :]
        flat: Buckets[tuple[float, float]] = Buckets(self.limit // 2, extremes)
        # each old leg holds until the next one starts; the last, if none follows, for ever
        untils = [after.start for after in [*old[1:], *recent[:1]]]
        untils += [math.inf] * (len(old) - len(untils))
        for leg, until in zip(old, untils, strict=True):
            kept = [(t, x) for t, x in leg.knots if t < until]
            if leg.cruise and kept and until < math.inf:  # where the cruise had taken it by then
                kept.append((until, leg.at(until)))
            for t, x in kept:
                flat.add(t, (t, x), x)
        cruise = 0.0 if recent else old[-1].cruise
        # legs wholly superseded (by one of the same instant) leave nothing behind
        self.legs = [Leg(tuple(flat.items()), cruise), *recent] if flat.added else recent
        self._starts = [leg.start for leg in self.legs]
        self._knots = sum(len(leg.knots) for leg in self.legs)

    def track(self) -> Track:
        return Track(tuple(self.legs))


class PathBuilder:
    """What `stage-emu plot` draws of one device, gathered record by record in bounded memory."""

    def __init__(self, device: str) -> None:
        self.device = device
        self.start = math.inf
        self.end = -math.inf
        self.tracks: dict[str, TrackBuilder] = {}
        self.arrivals: Buckets[Arrival] = Buckets(POINTS, ends)
        self.scan_marks: Buckets[ScanMark] = Buckets(POINTS, ends)
        self.laser: Buckets[tuple[float, int]] = Buckets(POINTS, extremes)

    def feed(self, record: dict[str, Any]) -> None:
        """One record of this device (already checked as a traffic record)."""
        t = float(record["t"])
        self.start, self.end = min(self.start, t), max(self.end, t)
        if record["dir"] != "ev":
            return
        ev = record.get("ev")
        if ev == MOVE:
            for axis, leg in _legs(record):
                self.tracks.setdefault(axis, TrackBuilder()).add(leg)
                self.start = min(self.start, leg.start)
        elif ev == "array_arrival":
            arrival = Arrival(t, self.arrivals.added + 1, int(record["i"]), int(record["j"]))
            self.arrivals.add(t, arrival)
        elif ev == "scan_sync":
            self.scan_marks.add(t, ScanMark(t, int(record["line"])))
        elif ev == "scan_pixels":
            self.scan_marks.add(t, ScanMark(t, int(record["line"]), int(record["count"])))
        elif ev == "ttl_out0":
            level = int(record["level"])
            self.laser.add(t, (t, level), level)

    def session(self) -> Session:
        """The session so far (ARRAY cells keep their arrival numbers when thinned)."""
        return Session(
            self.device,
            {axis: builder.track() for axis, builder in self.tracks.items()},
            self.start,
            self.end,
            self.arrivals.items(),
            self.scan_marks.items(),
            self.laser.items(),
        )


def _legs(record: dict[str, Any]) -> Iterable[tuple[str, Leg]]:
    cruise = record.get("cruise") or {}
    for axis, knots in record["path"].items():
        points = tuple((float(t), float(x)) for t, x in knots)
        if not points or not all(math.isfinite(t) and math.isfinite(x) for t, x in points):
            raise ValueError(f"axis {axis}: no finite knots")
        if any(b[0] < a[0] for a, b in itertools.pairwise(points)):
            raise ValueError(f"axis {axis}: knots out of time order")
        yield str(axis), Leg(points, float(cruise.get(axis, 0.0)))
