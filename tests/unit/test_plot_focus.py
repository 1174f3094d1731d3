"""The focus story in the traffic log and `stage-emu plot`'s reading and figure of it: CRISP's `crisp`
state events and `crisp_sample` lock-loop samples, AUTOFOCUS's `af_start`/`af_end` runs and
`af_sample` frames (emulator/tools/plot_focus.py, emulator/tools/plot_focus_figure.py). Per-update samples are
built only while a traffic log is kept and reach only the log; state and run events reach control
subscribers too. Real models under the real runner on a manual clock; synthetic logs for the reader."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import AF_SAMPLE, CRISP_SAMPLE, TrafficLog
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.tools.plot_focus import AfRun, StateChange
from emulator.tools.plot_scan import focus_device, read_focus, scan_records
from emulator.tools.readers import ReadError
from emulator.wire_time import FAST
from tests.support.memory_transport import MemoryTransport
from tests.support.model_harness import ModelHarness

matplotlib.use("Agg")
from emulator.tools.plot_focus_figure import draw_focus


def write_log(path: Path, records: list[dict[str, Any]]) -> Path:
    path.write_text(
        "".join(json.dumps({"wall": 0.0, "device": "stage", "dir": "ev", **r}) + "\n" for r in records)
    )
    return path


def crisp(
    t: float, state: str, error: float = 0.0, surface_um: float = 0.0, band: float = 10.0
) -> dict[str, Any]:
    reading = {"error": error, "offset": 0, "sum": 3000, "snr": 30.0, "surface_um": surface_um}
    return {
        "t": t,
        "ev": "crisp",
        "state": state,
        "previous": "?",
        "axis": "Z",
        "in_focus_counts": band,
        **reading,
    }


def sample(t: float, error: float, surface_um: float) -> dict[str, Any]:
    return {"t": t, "ev": CRISP_SAMPLE, "error": error, "surface_um": surface_um}


def z_move(t: float, *knots: tuple[float, float]) -> dict[str, Any]:
    return {"t": t, "ev": "move", "path": {"Z": [list(k) for k in knots]}}


CRISP_RECORDS = [
    crisp(1.0, "R"),
    crisp(1.1, "K", error=40.0),
    sample(1.11, 30.0, 0.4),
    z_move(1.11, (1.11, 0.0), (1.2, 0.4)),
    crisp(1.2, "F", error=5.0, surface_um=0.4),
    sample(1.3, 2.0, 0.6),
    crisp(2.0, "R", surface_um=1.0, band=20.0),
]


# ---- reading --------------------------------------------------------------------------------------


def test_crisp_states_readings_band_and_z_are_read(tmp_path: Path) -> None:
    focus = read_focus(write_log(tmp_path / "t.jsonl", CRISP_RECORDS))
    assert focus.crisp and not focus.autofocus and focus.axis == "Z"
    assert [(c.t, c.state, c.in_focus_counts) for c in focus.states] == [
        (1.0, "R", 10.0),
        (1.1, "K", 10.0),
        (1.2, "F", 10.0),
        (2.0, "R", 20.0),
    ]
    assert [(r.t, r.error, r.surface_um) for r in focus.readings] == [
        (1.0, 0.0, 0.0),
        (1.1, 40.0, 0.0),
        (1.11, 30.0, 0.4),
        (1.2, 5.0, 0.4),
        (1.3, 2.0, 0.6),
        (2.0, 0.0, 1.0),
    ], "state changes and lock-loop samples, in time order"
    assert focus.state_at(0.5) is None
    assert focus.state_at(1.25) == StateChange(1.2, "F", 10.0)
    assert focus.z_um(1.0) == 0.0 and focus.z_um(1.155) == pytest.approx(0.2) and focus.z_um(3.0) == 0.4
    assert focus.z_times() == [1.0, 1.11, 1.2, 2.0]


def test_af_runs_pair_start_and_end_and_samples_are_read(tmp_path: Path) -> None:
    records = [
        {"t": 0.5, "ev": "af_end", "result": "halted", "calibrating": True},  # began before the log
        {"t": 1.0, "ev": "af_start", "calibrating": False, "axis": "F", "start_um": 0.0, "range_um": 100.0},
        {"t": 1.1, "ev": AF_SAMPLE, "z_um": -50.0, "value": 40, "filtered": None},
        {"t": 1.2, "ev": AF_SAMPLE, "z_um": -49.0, "value": 41, "filtered": 40.5},
        {
            "t": 2.0,
            "ev": "af_end",
            "result": "focused",
            "calibrating": False,
            "peak": 980.5,
            "peak_um": 12.25,
        },
        {"t": 3.0, "ev": "af_start", "calibrating": True, "axis": "F", "start_um": 12.0, "range_um": 100.0},
    ]
    focus = read_focus(write_log(tmp_path / "t.jsonl", records))
    assert focus.autofocus and not focus.crisp and focus.axis == "F"
    assert focus.runs == [
        AfRun(0.5, True, 0.5, "halted"),
        AfRun(1.0, False, 2.0, "focused", 980.5, 12.25),
        AfRun(3.0, True),
    ], "a run the log saw only end of starts with the log; one still running has no end"
    assert [(s.z_um, s.value, s.filtered) for s in focus.samples] == [(-50.0, 40, None), (-49.0, 41, 40.5)]


def test_the_focus_figure_is_chosen_for_a_device_with_focus_records() -> None:
    moves = [{**z_move(1.0, (1.0, 0.0)), "dir": "ev", "device": name} for name in "ab"]
    start = {"t": 1.0, "dir": "ev", "device": "b", "ev": "af_start", "calibrating": False}
    focusing = scan_records([*moves, {**crisp(1.0, "R"), "dir": "ev", "device": "b"}])
    assert focus_device(focusing, "b") == "b"
    assert focus_device(focusing, "a") is None
    assert focus_device(focusing, None) is None, "two devices: the path figure asks for --device"
    assert focus_device(scan_records([start, moves[1]]), None) == "b"
    assert focus_device(scan_records(moves[:1]), None) is None


@pytest.mark.parametrize(
    ("records", "device", "message"),
    [
        (
            [z_move(1.0, (1.0, 0.0))],
            None,
            "no CRISP or AUTOFOCUS records: was the device served with either?",
        ),
        ([crisp(1.0, "R"), {**crisp(1.0, "R"), "device": "other"}], None, "focus records of several devices"),
        ([crisp(1.0, "R")], "ghost", "no device 'ghost' (the log holds: stage)"),
        ([{"t": 1.0, "ev": CRISP_SAMPLE, "error": 3}], None, "a malformed stage focus record ('surface_um')"),
    ],
)
def test_a_log_without_a_focus_story_is_one_line(
    tmp_path: Path, records: list[dict[str, Any]], device: str | None, message: str
) -> None:
    with pytest.raises(ReadError) as caught:
        read_focus(write_log(tmp_path / "t.jsonl", records), device)
    assert str(caught.value).startswith(str(tmp_path)) and message in str(caught.value)


# ---- drawing --------------------------------------------------------------------------------------


def test_the_figure_has_a_panel_per_story_and_a_symlog_error_beside_a_large_step(tmp_path: Path) -> None:
    big = [*CRISP_RECORDS, sample(1.5, 800.0, 8.0)]
    runs = [
        {"t": 2.5, "ev": "af_start", "calibrating": False},
        {"t": 2.9, "ev": "af_end", "result": "no_contrast"},
    ]
    runs[1]["calibrating"] = False
    focus = read_focus(write_log(tmp_path / "t.jsonl", big + runs))
    output = tmp_path / "focus.svg"
    draw_focus(focus, output)
    svg = output.read_text()
    for text in ("focus axis", "surface", "in-focus band", "error (counts, symlog)", "F  in focus"):
        assert f"<!-- {text} -->" in svg, text
    for text in ("AUTOFOCUS focus value", "AUTOFOCUS runs (hatched: calibration)", "no_contrast"):
        assert f"<!-- {text} -->" in svg, text
    assert "stage: CRISP and AUTOFOCUS focus, 1.00–2.90 s device time" in svg


def test_plot_path_draws_the_stage_path_of_a_focus_session(tmp_path: Path) -> None:
    log = write_log(tmp_path / "t.jsonl", CRISP_RECORDS)
    output = tmp_path / "p.svg"
    result = CliRunner().invoke(main, ["plot", str(log), "-o", str(output), "--path", "--axes", "xz"])
    assert result.exit_code == 0, result.output
    assert "X-Z path" in output.read_text() and "CRISP focus error" not in output.read_text()
    moves_only = write_log(tmp_path / "m.jsonl", [z_move(1.0, (1.0, 0.0))])
    result = CliRunner().invoke(main, ["plot", str(moves_only), "-o", str(output), "--focus"])
    assert result.exit_code == 1
    assert (
        result.stderr
        == f"stage-emu: {moves_only}: no CRISP or AUTOFOCUS records: was the device served with either?\n"
    )


# ---- the models' events ---------------------------------------------------------------------------


@dataclass
class Served:
    runner: DeviceRunner
    clock: ManualClock
    port: MemoryTransport
    published: list[dict[str, Any]] = field(default_factory=list)

    def send(self, data: bytes, then: float = 0.5) -> bytes:
        self.port.take()
        self.port.send(data)
        self.clock.advance(then)
        return self.port.take()

    def input(self, input_name: str, /, **params: Any) -> None:
        self.runner.call(lambda now: self.runner.device.control_input(input_name, params, now))


def serve(log: Path, profile: str) -> Served:
    clock = ManualClock()
    loaded = load_profile(profile)
    registered = family(loaded.family)
    assert registered is not None
    published: list[dict[str, Any]] = []
    runner = DeviceRunner(
        lambda now: registered.factory("stage", loaded, now, DeviceServices()),
        clock,
        traffic=TrafficLog(log),
        on_event=lambda _, event: published.append(event),
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, FAST)
    port.attach(LineSettings(9600, None, None, 1, False, False))
    clock.advance(2.0)  # past the power-up silence
    return Served(runner, clock, port, published)


def logged(log: Path) -> list[dict[str, Any]]:
    return [r for r in map(json.loads, log.read_text().splitlines()) if r["dir"] == "ev"]


def test_crisp_state_changes_reach_subscribers_and_lock_loop_samples_only_the_log(tmp_path: Path) -> None:
    served = serve(tmp_path / "t.jsonl", "ms2000-crisp")
    assert served.send(b"LK\r") == b":A\r\n"
    assert served.send(b"LK F=83\r") == b":A\r\n"
    served.input("crisp", drift_um_per_s=1.0)
    served.clock.advance(1.0)
    served.runner.close()
    states = [(e["previous"], e["state"]) for e in served.published if e["ev"] == "crisp"]
    assert states == [("I", "R"), ("R", "K"), ("K", "F")]
    assert not [e for e in served.published if e["ev"] in (CRISP_SAMPLE, "move")]
    records = logged(tmp_path / "t.jsonl")
    samples = [r for r in records if r["ev"] == CRISP_SAMPLE]
    assert 140 <= len(samples) <= 160, "one per 10 ms lock-loop update (UL Y)"
    assert {"error", "surface_um"} <= set(samples[-1]) and samples[-1]["surface_um"] == pytest.approx(
        1.0, abs=0.02
    )
    locked = next(r for r in records if r["ev"] == "crisp" and r["state"] == "F")
    assert {k: locked[k] for k in ("axis", "in_focus_counts", "offset", "sum")} == {
        "axis": "Z",
        "in_focus_counts": 10.0,
        "offset": 0,
        "sum": 3000,
    }


def test_af_runs_reach_subscribers_with_their_result_and_frames_only_the_log(tmp_path: Path) -> None:
    served = serve(tmp_path / "t.jsonl", "ms2000-af")
    served.input("focus", peak_um=5.0)
    assert served.send(b"AF\r", then=6.0) == b":A\r\n"
    served.input("focus", amplitude=0.0)
    assert served.send(b"AF\r", then=6.0) == b":N-5\r\n"
    served.send(b"AF\r", then=0.2)
    served.send(b"\\\r")
    served.input("button", name="at")  # a run without a reply (MS-AF-3) at release, ended by a reset
    served.clock.advance(0.3)
    served.send(b"~\r")
    served.runner.close()
    ends = [(e["result"], e.get("peak_um")) for e in served.published if e["ev"] == "af_end"]
    assert ends[0][0] == "focused" and ends[0][1] == pytest.approx(5.0, abs=1.0)
    assert [result for result, _ in ends[1:]] == ["no_contrast", "halted", "halted"]
    assert len([e for e in served.published if e["ev"] == "af_start"]) == 4
    assert not [e for e in served.published if e["ev"] == AF_SAMPLE]
    frames = [r for r in logged(tmp_path / "t.jsonl") if r["ev"] == AF_SAMPLE]
    assert len(frames) > 60 and {"z_um", "value", "filtered"} == set(frames[0]) - {
        "t",
        "wall",
        "device",
        "dir",
        "ev",
    }


@pytest.mark.parametrize(
    ("profile", "commands"), [("ms2000-crisp", [b"LK\r", b"LK F=83\r"]), ("ms2000-af", [b"AF\r"])]
)
def test_without_a_traffic_log_no_sample_is_built(profile: str, commands: list[bytes]) -> None:
    loaded = load_profile(profile)
    registered = family(loaded.family)
    assert registered is not None
    harness = ModelHarness(
        lambda now: registered.factory("stage", loaded, now, DeviceServices()), paced=False
    )
    harness.advance(2.0)
    for command in commands:
        harness.write(command)
        harness.advance(harness.now + 0.1)
    harness.advance(harness.now + 5.0)
    names = {e["ev"] for e in harness.take_events()}
    assert names & {"crisp", "af_end"}, "the few events are pushed"
    assert not names & {CRISP_SAMPLE, AF_SAMPLE, "move"}
