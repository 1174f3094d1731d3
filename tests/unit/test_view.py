"""`stage-emu view`: rows from `list`, snapshots, events and traffic records (emulator/tools/view.py),
their rendering, and the command's one-line failure without a daemon."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from rich.console import Console

from emulator.cli import main
from emulator.cli.view import render
from emulator.device import HostLine
from emulator.hosting.trafficlog import traffic_entry
from emulator.tools.view import EVENTS_KEPT, EXCHANGES_KEPT, ExchangeRow, ViewState, event_line

LISTING: list[dict[str, Any]] = [
    {
        "device": "ms2000",
        "family": "ms2000",
        "profile": "ms2000",
        "ports": [
            {
                "port": "main",
                "path": "/run/x/ms2000",
                "attached": True,
                "host": "9600 8N1 rtscts",
                "timing": "realistic",
                "faults": {"hung": False, "drop_replies": 2},
                "stats": {"output_dropped": 0, "input_discarded": 3},
            }
        ],
    },
    {"device": "mp285", "family": "mp285", "profile": "mp285", "ports": []},
]
MS2000_SNAPSHOT: dict[str, Any] = {
    "axes": {"X": {"user_mm": 1.5}, "Y": {"user_mm": -0.25}},
    "busy": True,
    "ttl_out0": 1,
    "ttl_out0_pwm": 0.0,
    "lcd": ["X1.500 Y-0.250", "RB 0/0"],
}
MP285_SNAPSHOT: dict[str, Any] = {
    "state": "MOVING",
    "position": {"um": {"X": 10.0, "Y": 0.0, "Z": -2.5}},
    "display": ["X:+10.00", ""],
}


def loaded() -> ViewState:
    state = ViewState()
    state.apply_list(LISTING)
    state.apply_snapshot("ms2000", MS2000_SNAPSHOT)
    state.apply_snapshot("mp285", MP285_SNAPSHOT)
    return state


def test_rows_from_list_and_snapshots() -> None:
    state = loaded()
    ms, mp = state.devices["ms2000"], state.devices["mp285"]
    assert ms.positions == "X=1.5000mm Y=-0.2500mm"
    assert (ms.busy, ms.ttl_out0, ms.lcd) == ("busy", "high", ["X1.500 Y-0.250", "RB 0/0"])
    (port,) = ms.ports
    assert (port.attached, port.host, port.timing) == ("yes", "9600 8N1 rtscts", "realistic")
    assert port.stats == "input_discarded=3 faults: drop_replies"
    assert mp.positions == "X=10.00µm Y=0.00µm Z=-2.50µm"
    assert (mp.busy, mp.ttl_out0, mp.lcd) == ("moving", "-", ["X:+10.00", ""])


def test_a_device_no_longer_listed_goes_away() -> None:
    state = loaded()
    state.apply_list(LISTING[:1])
    assert list(state.devices) == ["ms2000"]


def test_events_mark_their_device_stale_and_are_kept() -> None:
    state = loaded()
    assert state.apply_event({"ev": "ttl_out0", "level": 0, "t": 1.25, "device": "ms2000"}) == "ms2000"
    assert list(state.devices["ms2000"].events) == ["t=1.250 ttl_out0 level=0"]
    assert state.apply_event({"ev": "move", "path": {}, "device": "ms2000"}) == "ms2000"
    assert len(state.devices["ms2000"].events) == 1  # per-leg records are not listed
    assert state.apply_event({"ev": "orphan"}) is None
    for i in range(EVENTS_KEPT + 3):
        state.apply_event({"ev": "move_complete", "n": i, "device": "mp285"})
    assert len(state.devices["mp285"].events) == EVENTS_KEPT
    state.apply_event({"ev": "dropped", "count": 4, "device": "mp285"})
    assert state.dropped == 4


def test_event_line_without_time() -> None:
    assert event_line({"ev": "button", "name": "zero", "device": "d"}) == 'button name="zero"'


def traffic(t: float, direction: str, data: bytes, kind: str, summary: str | None = None) -> dict[str, Any]:
    """A pushed traffic record, as the control channel sends it."""
    return {"ev": "traffic", **traffic_entry(t, "ms2000", "main", direction, data, summary, kind)}


def test_traffic_records_become_exchanges_with_flags() -> None:
    state = loaded()
    for record in (
        traffic(1.0, "rx", b"W X Y\r", "frame", "W X Y [WHERE]"),
        traffic(1.008, "tx", b":A 0 0\r\n", "reply", ":A 0 0\\r\\n (reply to W X Y [WHERE])"),
        traffic(2.0, "rx", b"\x1e", "garbled", "the device read 1E from the host's 63"),
        traffic(2.1, "rx", b"?\r", "stray", "bad frame"),
        traffic(2.2, "tx", b"1\r", "lost", "not sent: drop fault: error '1'"),
        traffic(3.0, "tx", b"N\r\n", "unsolicited", "status"),
        traffic(4.0, "rx", b"c\r", "frame"),
    ):
        assert state.apply_event(record) == "ms2000"
    rows = list(state.devices["ms2000"].exchanges)
    assert rows == [
        ExchangeRow(1.0, "main", "", "W X Y [WHERE]", '":A 0 0\\r\\n"', pytest.approx(8.0)),
        ExchangeRow(2.0, "main", "GARBLED", '"\\x1e" the device read 1E from the host\'s 63', ""),
        ExchangeRow(
            2.1,
            "main",
            "STRAY reply LOST",
            '"?\\r" bad frame',
            "\"1\\r\" (not sent: drop fault: error '1')",
            pytest.approx(100.0),
        ),
        ExchangeRow(3.0, "main", "UNSOLICITED", "", '"N\\r\\n" status'),
    ]
    state.expire(float("inf"))  # `c` waits for its reply until then
    assert state.devices["ms2000"].exchanges[-1] == ExchangeRow(
        4.0, "main", "", '"c\\r"', "no reply within 2 s"
    )
    for i in range(EXCHANGES_KEPT):
        state.apply_event(traffic(5.0 + i, "tx", b"x", "unsolicited"))
    assert len(state.devices["ms2000"].exchanges) == EXCHANGES_KEPT


def test_a_malformed_traffic_record_is_skipped() -> None:
    state = loaded()
    assert state.apply_event({"ev": "traffic", "device": "ms2000", "dir": "rx"}) is None
    assert not state.devices["ms2000"].exchanges


def test_rendering() -> None:
    state = loaded()
    state.apply_event({"ev": "move_complete", "t": 2.0, "device": "ms2000"})
    state.apply_event(traffic(1.0, "rx", b"W X Y\r", "frame", "W X Y [WHERE]"))
    state.apply_event(traffic(1.008, "tx", b":A 0 0\r\n", "reply", ":A 0 0\\r\\n (reply to W X Y [WHERE])"))
    state.apply_event(traffic(2.0, "rx", b"\x1e", "garbled", "the device read 1E"))
    console = Console(record=True, width=120)
    console.print(render(state))
    text = console.export_text()
    for expected in (
        "ms2000 ms2000 (ms2000)",
        "X=1.5000mm",
        "busy",
        "RB 0/0",
        "high",
        "9600 8N1 rtscts",
        "/run/x/ms2000",
        "t=2.000 move_complete",
        '1.000 main W X Y [WHERE] -> ":A 0 0\\r\\n" 8.0 ms',
        'GARBLED "\\x1e" the device read 1E',
        "mp285 mp285 (mp285)",
        "moving",
        "(none yet)",
        "keeps no traffic log",
    ):
        assert expected in " ".join(text.split()), expected
    state.apply_list([{**LISTING[0], "traffic_log": "/tmp/t.jsonl"}])
    console = Console(record=True, width=120)
    console.print(render(state))
    assert "Traffic log: /tmp/t.jsonl" in console.export_text()


def test_no_daemon_is_one_line_and_exit_1(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["view", "--control", str(tmp_path / "none.sock")])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1
    assert "cannot reach the daemon" in result.output


def test_a_pty_host_line_says_what_is_not_visible_and_paths_are_never_cut() -> None:
    """A PTY shows no data bits or parity: the view says so (HostLine.describe) instead of a bare
    `9600 ??1`; a narrow terminal folds a port's path rather than cutting it."""
    port = {
        **LISTING[0]["ports"][0],
        "path": "/run/user/1000/stage-emu/ms2000",
        "host": HostLine(baud=9600, stop_bits=1, rtscts=False, xonxoff=False).describe(),
    }
    state = ViewState()
    state.apply_list([{**LISTING[0], "ports": [port]}])
    wide = Console(record=True, width=200)
    wide.print(render(state))
    assert "9600 ??1 (data bits, parity not visible)" in wide.export_text()
    narrow = Console(record=True, width=80)
    narrow.print(render(state))
    text = narrow.export_text()
    assert "/run/user/1" in text and "/ms2000" in text and "stage-emu…" not in text
