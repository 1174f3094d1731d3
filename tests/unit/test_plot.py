"""`stage-emu plot`'s reading of a traffic log (emulator/tools/plot.py): positions from the devices' own
`move` records, interpolated between knots and superseded by later records; ARRAY, SCAN and OUT0
events; one-line errors for logs it cannot plot. The MS2000 and MP-285 records come from the real
models under the real runner on a manual clock, with a traffic log."""

from __future__ import annotations

import json
import tracemalloc
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import TrafficLog
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.tools.plot import POINTS, Leg, Session, Track, TrackBuilder
from emulator.tools.plot_scan import read_log, read_session
from emulator.tools.readers import ReadError
from emulator.wire_time import FAST
from protocols import mp285
from tests.support.memory_transport import MemoryTransport
from tests.support.model_harness import ModelHarness


def write_log(path: Path, records: list[dict[str, Any]]) -> Path:
    path.write_text("".join(json.dumps({"wall": 0.0, **r}) + "\n" for r in records))
    return path


def move(t: float, axis: str, *knots: tuple[float, float], cruise: float | None = None) -> dict[str, Any]:
    record: dict[str, Any] = {"t": t, "device": "stage", "dir": "ev", "ev": "move"}
    record["path"] = {axis: [list(k) for k in knots]}
    if cruise is not None:
        record["cruise"] = {axis: cruise}
    return record


def event(t: float, name: str, **fields: Any) -> dict[str, Any]:
    return {"t": t, "device": "stage", "dir": "ev", "ev": name, **fields}


# ---- interpolation ------------------------------------------------------------------------------


def test_a_leg_is_linear_between_knots_rests_at_its_ends_and_cruises_after_the_last() -> None:
    leg = Leg(((1.0, 0.0), (1.5, 100.0), (2.0, 150.0)))
    assert [leg.at(t) for t in (0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 9.0)] == [0, 0, 50, 100, 125, 150, 150]
    cruising = Leg(((1.0, 0.0), (2.0, 10.0)), cruise=-4.0)
    assert cruising.at(4.0) == pytest.approx(2.0)


def test_a_later_record_supersedes_an_earlier_one_from_its_first_knot() -> None:
    """A move re-planned at t=1.5 (or halted there) is no longer where the first record went."""
    first = Leg(((1.0, 0.0), (3.0, 200.0)))
    halt = Leg(((1.5, 50.0),))
    track = Track((first, halt))
    assert [track.at(t) for t in (0.0, 1.25, 1.5, 2.5)] == [0.0, 25.0, 50.0, 50.0]
    assert track.times() == [1.0, 1.5], "the first record's end knot is superseded"


def test_session_events_laser_level_and_sample_times(tmp_path: Path) -> None:
    log = write_log(
        tmp_path / "t.jsonl",
        [
            {"t": 0.5, "device": "stage", "port": "main", "dir": "rx", "hex": "41 52 0d", "kind": "frame"},
            move(1.0, "X", (1.0, 0.0), (2.0, 100.0)),
            event(1.2, "ttl_out0", level=0),
            event(2.0, "array_arrival", i=1, j=1),
            event(2.1, "scan_sync", line=1),
            event(2.3, "scan_pixels", line=1, count=42),
            event(2.4, "array_arrival", i=2, j=1),
            event(2.6, "ttl_out0", level=1),
        ],
    )
    session = read_session(log)
    assert (session.device, session.start, session.end) == ("stage", 0.5, 2.6)
    assert [(a.number, a.i, a.j, a.t) for a in session.arrivals] == [(1, 1, 1, 2.0), (2, 2, 1, 2.4)]
    assert [(m.line, m.pixels) for m in session.scan_marks] == [(1, None), (1, 42)]
    assert [session.laser_on(t) for t in (1.0, 1.5, 2.7)] == [True, False, True], "high before a fall"
    assert session.at("X", 1.5) == 50.0 and session.at("Y", 1.5) == 0.0, "an axis never moved is at 0"
    assert session.moved("X") and not session.moved("Y")
    assert session.sample_times() == [0.5, 1.0, 1.2, 2.0, 2.6]


def test_no_laser_edges_means_no_laser_styling() -> None:
    session = Session("stage", {"X": Track((Leg(((0.0, 0.0),)),))}, 0.0, 1.0)
    assert session.laser_on(0.5) is None
    assert not session.moved("X")


# ---- bad logs -----------------------------------------------------------------------------------


#: the fields every record of a real log has besides its own (emulator/hosting/trafficlog.py)
RX = {"wall": 0.0, "device": "stage", "dir": "rx", "port": "main"}
EV = {"wall": 0.0, "device": "s", "dir": "ev"}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "empty, not a traffic log"),
        ("hello\nworld\n", ":1: not a traffic log: not JSON (Expecting value, column 1)"),
        ('{"a": 1}\n', ":1: not a traffic log record (no t, wall and device)"),
        (
            '{"t": 1, "device": "stage", "dir": "rx"}\n',
            ":1: not a traffic log record (no t, wall and device)",
        ),
        (json.dumps({**RX, "t": 1, "hex": ""}) + "\n", "no move records: was it written by"),
        (
            json.dumps({**EV, "t": 1, "ev": "move", "path": {"X": []}}) + "\n",
            "a malformed s event record (axis X: no finite knots)",
        ),
    ],
)
def test_a_log_it_cannot_plot_is_one_line_naming_the_file(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text(content)
    with pytest.raises(ReadError, match="^" + str(path)) as caught:
        read_session(path)
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(ReadError, match="no such file"):
        read_session(tmp_path / "nope.jsonl")
    with pytest.raises(ReadError, match="is a directory"):
        read_session(tmp_path)


def test_a_last_line_cut_short_is_left_out(tmp_path: Path) -> None:
    """The daemon may stop in the middle of a write."""
    path = write_log(tmp_path / "t.jsonl", [move(1.0, "X", (1.0, 5.0))])
    path.write_text(path.read_text() + '{"t": 2.0, "dev')
    assert read_log(path).devices["stage"].path.end == 1.0


def test_devices_are_chosen_by_name_or_by_being_the_only_one_that_moved(tmp_path: Path) -> None:
    other = {**move(1.0, "X", (1.0, 7.0)), "device": "other"}
    quiet = {**RX, "t": 1.0, "device": "quiet", "hex": ""}
    log = write_log(tmp_path / "t.jsonl", [move(1.0, "X", (1.0, 5.0)), quiet])
    assert read_session(log).device == "stage"
    with pytest.raises(ReadError, match=r"no move records of device 'quiet'"):
        read_session(log, "quiet")
    with pytest.raises(ReadError, match=r"no device 'ghost' \(the log holds: quiet, stage\)"):
        read_session(log, "ghost")
    write_log(log, [move(1.0, "X", (1.0, 5.0)), other])
    with pytest.raises(ReadError, match=r"several devices \(other, stage\): choose one with --device"):
        read_session(log)
    assert read_session(log, "other").at("X", 2.0) == 7.0


# ---- records from the models --------------------------------------------------------------------


@dataclass
class Served:
    clock: ManualClock
    port: MemoryTransport
    traffic: TrafficLog

    def send(self, data: bytes, then: float = 3.0) -> bytes:
        self.port.take()
        self.port.send(data)
        self.clock.advance(then)
        return self.port.take()


def serve(tmp_path: Path, profile: str) -> Served:
    clock = ManualClock()
    loaded = load_profile(profile)
    registered = family(loaded.family)
    assert registered is not None
    traffic = TrafficLog(tmp_path / "traffic.jsonl")
    runner = DeviceRunner(
        lambda now: registered.factory("stage", loaded, now, DeviceServices()), clock, traffic=traffic
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, FAST)
    port.attach(LineSettings(9600, None, None, 1, False, False))
    clock.advance(2.0)  # past the power-up silence
    return Served(clock, port, traffic)


def test_ms2000_moves_halts_and_open_ended_motion_are_recorded(tmp_path: Path) -> None:
    served = serve(tmp_path, "ms2000")
    served.send(b"M X=10000 Y=-5000\r")  # 0.1 µm units: X to 1 mm, Y to -0.5 mm
    started = served.clock.now()
    served.send(b"M X=100000\r", then=0.5)  # 9 mm more: still on its way when halted
    served.send(b"\\\r", then=1.0)
    halted_at = served.send(b"W X\r")
    served.send(b"VE X=0.5\r", then=1.0)
    served.traffic.close()
    session = read_session(tmp_path / "traffic.jsonl")
    assert session.at("X", started) == pytest.approx(1000.0) and session.at("Y", started) == -500.0
    halted_um = float(halted_at.split()[1]) / 10
    assert session.at("X", started + 2.0) == pytest.approx(halted_um, abs=0.05)
    assert 1000 < halted_um < 10000
    cruise = [leg.cruise for leg in session.tracks["X"].legs]
    assert cruise[-1] == pytest.approx(500.0), "VE: 0.5 mm/s after its ramp, until the next record"


def test_ms2000_builds_no_move_records_without_a_traffic_log() -> None:
    profile = load_profile("ms2000")
    registered = family(profile.family)
    assert registered is not None
    harness = ModelHarness(
        lambda now: registered.factory("stage", profile, now, DeviceServices()), paced=False
    )
    harness.advance(2.0)
    harness.write(b"M X=10000\r")
    harness.advance(4.0)
    assert harness.take_events("move_complete") and not harness.take_events("move")


def test_mp285_runs_and_halts_are_recorded(tmp_path: Path) -> None:
    served = serve(tmp_path, "mp285")
    served.send(mp285.Move(2500, 1000, 0).encode())  # µsteps: 25 per µm
    started = served.clock.now()
    served.send(mp285.Move(250000, 1000, 0).encode(), then=0.2)
    served.send(b"\x03", then=1.0)  # ^C halts it (MP-48)
    stopped = served.send(b"c\r")
    served.traffic.close()
    session = read_session(tmp_path / "traffic.jsonl")
    assert [session.at(axis, started) for axis in "XYZ"] == [100.0, 40.0, 0.0]
    x_usteps = int.from_bytes(stopped[:4], "little", signed=True)
    assert 100 < session.at("X", session.end) == pytest.approx(x_usteps / 25, abs=0.05)


# ---- long logs (issue "Hardening, round two", item 5) ---------------------------------------------


def write_raster(path: Path, moves: int) -> Path:
    """A serpentine of `moves` X moves between 0 and 1000 µm, Y a step per line, a cell arrival per
    move; one move in the middle overshoots to 5000 µm."""
    with path.open("w") as out:
        x, t = 0.0, 1.0
        for n in range(moves):
            target = 1000.0 if x == 0.0 else 0.0
            if n == moves // 2:
                target = 5000.0
            knots = {
                "X": [[t, x], [t + 0.05, target]],
                "Y": [[t, n // 2 * 10.0], [t + 0.05, (n + 1) // 2 * 10.0]],
            }
            out.write(json.dumps({"wall": 0.0, **event(t, "move"), "path": knots}) + "\n")
            out.write(json.dumps({"wall": 0.0, **event(t + 0.05, "array_arrival", i=n, j=0)}) + "\n")
            x, t = target, t + 0.1
    return path


def test_a_long_log_is_thinned_to_a_bounded_path_that_keeps_its_extent_and_end(tmp_path: Path) -> None:
    """Before: every record stayed in memory as a dict and every knot was drawn (a 45 MB log took
    866 MB and 38 s to plot)."""
    moves = 8000  # four times the knots an axis keeps
    log = write_raster(tmp_path / "t.jsonl", moves)
    tracemalloc.start()
    try:
        session = read_session(log)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8e6, f"{peak / 1e6:.1f} MB held while reading (before: 25 MB)"
    for track in session.tracks.values():
        assert sum(len(leg.knots) for leg in track.legs) <= 2 * POINTS
    times = session.sample_times()
    assert len(times) <= 3 * POINTS
    xs = [session.at("X", t) for t in times]
    assert (min(xs), max(xs)) == (0.0, 5000.0), "min/max per bucket keeps the overshoot"
    assert session.at("Y", session.end) == moves // 2 * 10.0
    assert session.at("X", session.end) == (1000.0 if moves % 2 else 0.0)
    assert session.end == pytest.approx(1.0 + (moves - 1) * 0.1 + 0.05)
    assert len(session.arrivals) <= POINTS and session.arrivals[-1].number == moves
    assert session.arrivals[0].number == 1, "thinned cells keep their arrival numbers"


def test_thinning_keeps_a_late_record_its_supersession_and_a_last_cruise() -> None:
    """The latest legs stay as they came: a halt's record, written after later ones, still cuts the
    move it halted; a track thinned to its last leg keeps that leg's cruise."""
    builder = TrackBuilder(limit=40)
    for n in range(100):
        builder.add(Leg(((n, 0.0), (n + 0.5, 10.0))))
    builder.add(Leg(((99.25, 3.0),)))  # written late: a halt at 99.25 of the move that began at 99
    track = builder.track()
    assert sum(len(leg.knots) for leg in track.legs) <= 2 * 40
    assert (track.at(99.1), track.at(99.25), track.at(99.4)) == (pytest.approx(2.0), 3.0, 3.0)
    assert all(0.0 <= track.at(t / 10) <= 10.0 for t in range(990)), "within its extent"
    assert max(x for leg in track.legs for _, x in leg.knots) == 10.0
    spinning = TrackBuilder(limit=4)
    for n in range(6):
        spinning.add(Leg(((n, 0.0), (n + 0.5, 1.0), (n + 0.75, 2.0)), cruise=4.0 if n == 5 else 0.0))
    assert spinning.track().at(6.75) == pytest.approx(6.0), "the cruise after the last knot stays"
