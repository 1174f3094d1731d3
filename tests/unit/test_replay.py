"""Replaying a session (emulator/tools/replay.py): the comparison on synthetic exchanges, the host side
played on the in-process emulator, and the `replay`/`proxy` commands' exit codes and messages."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import pytest
import serial
from click.testing import CliRunner, Result

from emulator.cli import main
from emulator.device import LineSettings
from emulator.tools.replay import ReplayOptions, _timing, compare, emulator_url, open_port, play, replay
from emulator.tools.session import (
    RX,
    TX,
    Chunk,
    Event,
    Header,
    Session,
    SessionWriter,
    decode,
    iter_decode,
    load_session,
)
from emulator.tools.session_decode import Exchange

LINE = LineSettings(baud=9600, data_bits=8, parity="none", stop_bits=1, rtscts=False, xonxoff=False)
TOLERANCE = ReplayOptions(tolerance_s=0.005)
#: how long `play` may wait for reply bytes in the test of that wait
BYTES_WAIT_S = 20.0


def chunks(*events: tuple[float, str, bytes]) -> list[Event]:
    return [Chunk(*event) for event in events]


def differences(expected: list[Event], got: list[Event], options: ReplayOptions = TOLERANCE) -> list[str]:
    _count, found = compare("ms2000", decode("ms2000", expected), decode("ms2000", got), options)
    return [d.line("ms2000") for d in found]


RECORDED = chunks(
    (1.0, RX, b"W X\r"), (1.004, TX, b":A"), (1.010, TX, b" 0\r\n"), (2.0, RX, b"/\r"), (2.005, TX, b"N\r\n")
)


def test_the_same_replies_within_the_tolerance_are_no_difference() -> None:
    later = chunks(
        (1.1, RX, b"W X\r"),
        (1.107, TX, b":A 0\r\n"),
        (2.1, RX, b"/\r"),
        (2.106, TX, b"N\r"),
        (2.107, TX, b"\n"),
    )
    assert differences(RECORDED, later) == []
    assert compare("ms2000", decode("ms2000", RECORDED), decode("ms2000", later), TOLERANCE)[0] == 2


def test_a_different_reply_names_its_exchange() -> None:
    got = chunks((1.0, RX, b"W X\r"), (1.010, TX, b":A 5\r\n"), (2.0, RX, b"/\r"), (2.005, TX, b"N\r\n"))
    assert differences(RECORDED, got) == [
        '#1  1.000000  W X [WHERE]  "W X\\r": expected ":A 0\\r\\n" [10.0 ms], got ":A 5\\r\\n" [10.0 ms] '
        "(reply bytes differ)"
    ]


def test_a_reply_late_beyond_the_tolerance() -> None:
    got = chunks((1.0, RX, b"W X\r"), (1.004, TX, b":A 0\r\n"), (2.0, RX, b"/\r"), (2.020, TX, b"N\r\n"))
    assert differences(RECORDED, got) == [
        '#1  1.000000  W X [WHERE]  "W X\\r": ":A 0\\r\\n" [expected 10.0 ms, got 4.0 ms] '
        "(last byte 6.0 ms early (tolerance 5 ms))",
        '#2  2.000000  / [STATUS]  "/\\r": "N\\r\\n" [expected 5.0 ms, got 20.0 ms] '
        "(first byte 15.0 ms late (tolerance 5 ms); last byte 15.0 ms late (tolerance 5 ms))",
    ]
    assert differences(RECORDED, got, ReplayOptions(timing=False)) == []


def test_unsolicited_output_and_missing_exchanges() -> None:
    got = chunks((0.5, TX, b"?"), (1.0, RX, b"W X\r"), (1.004, TX, b":A"), (1.010, TX, b" 0\r\n"))
    assert differences(RECORDED, got) == [
        '#0  before the first request: expected nothing, got "?" (unsolicited output differs)',
        '#2  2.000000  / [STATUS]  "/\\r": expected "N\\r\\n" [5.0 ms], got no such exchange '
        "(missing in the replay)",
    ]


def session_of(*events: tuple[float, str, bytes]) -> Session:
    return Session(Header("ms2000", "ms2000", LINE), tuple(chunks(*events)))


def test_play_waits_for_the_bytes_the_host_had_before_writing_again() -> None:
    # recorded from a device far quicker than the emulator (1 ms replies): the second command, sent
    # on the first reply, must not overtake the emulator's slower reply
    session = session_of(
        (0.0, RX, b"W X\r"), (0.001, TX, b":A 0\r\n"), (0.002, RX, b"W Y\r"), (0.003, TX, b":A 0\r\n")
    )
    port = open_port(emulator_url("ms2000", "realistic"), LINE)
    try:
        # a wait for the reply's bytes far longer than any scheduling delay: had the host not seen
        # them come, its next write would wait all of it
        events = play(session, port, ReplayOptions(grace_s=0.05, wait_s=BYTES_WAIT_S))
    finally:
        port.close()
    first_reply_end = next(e.t for e in events if isinstance(e, Chunk) and e.data.endswith(b"\n"))
    second_request = [e for e in events if isinstance(e, Chunk) and e.direction == RX][1]
    # the host's recorded 1 ms reaction after the whole reply, never less (a loaded machine can only
    # add to it), and not the wait for bytes that never came
    assert 0.001 - 1e-5 <= second_request.t - first_reply_end < BYTES_WAIT_S / 2  # (timer rounding)
    found = decode("ms2000", events)
    assert [e.reply for e in found] == [b":A 0\r\n", b":A 0\r\n"]


def test_replay_on_the_fast_emulator() -> None:
    session = session_of(
        (0.0, RX, b"W X Y\r"), (0.01, TX, b":A 0 0\r\n"), (0.02, RX, b"FOO\r"), (0.03, TX, b":N-1\r\n")
    )
    with serial.serial_for_url("stageemu://ms2000?timing=fast", 9600, timeout=0.02) as port:
        result = replay(session, port, ReplayOptions(timing=False, grace_s=0.05))
    assert result.ok and result.compared == 2
    assert result.summary("here") == "2 exchanges replayed on here: no difference"


def test_emulator_urls() -> None:
    assert emulator_url("mp285a", "fast") == "stageemu://mp285a?timing=fast"
    assert emulator_url("/my dir/stage.yaml", "realistic") == (
        "stageemu://?profile=/my%20dir/stage.yaml&timing=realistic"
    )


# ---- the commands --------------------------------------------------------------------------------


def run(*args: str) -> Result:
    return CliRunner().invoke(main, list(args))


def write(path: Path, *events: tuple[float, str, bytes], device: str = "ms2000") -> Path:
    writer = SessionWriter(path, Header(device, device, LINE))
    for event in chunks(*events):
        writer.event(event)
    writer.close()
    return path


def test_replay_command_exit_codes(tmp_path: Path) -> None:
    good = write(tmp_path / "good.jsonl", (0.0, RX, b"W X\r"), (0.01, TX, b":A 0\r\n"))
    result = run("replay", str(good), "--timing", "fast")
    assert (result.exit_code, result.stdout) == (
        0,
        "1 exchanges replayed on stageemu://ms2000?timing=fast: no difference (timing not compared)\n",
    )
    wrong = write(tmp_path / "wrong.jsonl", (0.0, RX, b"W X\r"), (0.01, TX, b":A 7\r\n"))
    result = run("replay", str(wrong), "--timing", "fast")
    assert result.exit_code == 1
    assert result.stdout.splitlines()[0].startswith('#1  0.000000  W X [WHERE]  "W X\\r": expected ":A 7')


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["{tmp}/missing.jsonl"], "{tmp}/missing.jsonl: no such file"),
        (["{tmp}/bad.jsonl"], "{tmp}/bad.jsonl:1: not a session file: not JSON"),
        (
            ["{tmp}/good.jsonl", "--profile", "mp285"],
            "profile mp285 is for the mp285; the session was recorded on the ms2000",
        ),
        (["{tmp}/good.jsonl", "--profile", "nope"], "nope: no such profile"),
        (["{tmp}/good.jsonl", "--port", "{tmp}/ttyNONE"], "cannot open {tmp}/ttyNONE"),
        (["{tmp}/good.jsonl", "--save-test", "a b"], "--save-test 'a b': a name of letters"),
        (
            ["{tmp}/good.jsonl", "--save-test", "{tmp}/good.jsonl"],
            "--save-test: {tmp}/good.jsonl already exists",
        ),
    ],
)
def test_replay_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    write(tmp_path / "good.jsonl", (0.0, RX, b"/\r"), (0.01, TX, b"N\r\n"))
    (tmp_path / "bad.jsonl").write_text("{oops\n")
    result = run("replay", *(a.format(tmp=tmp_path) for a in args))
    assert result.exit_code == 2
    assert result.stderr.startswith("stage-emu: " + message.format(tmp=tmp_path))
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


def test_save_test_writes_a_conformance_case(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    session = write(tmp_path / "s.jsonl", (0.0, RX, b"/\r"), (0.01, TX, b"N\r\n"))
    monkeypatch.chdir(tmp_path)
    result = run("replay", str(session), "--timing", "fast", "--save-test", "idle-poll")
    assert result.exit_code == 2 and "no tests/conformance here" in result.stderr
    (tmp_path / "tests" / "conformance").mkdir(parents=True)
    result = run("replay", str(session), "--timing", "fast", "--save-test", "idle-poll")
    saved = tmp_path / "tests/conformance/ms2000/sessions/idle-poll.jsonl"
    assert result.exit_code == 0, result.output
    assert (
        result.stdout.splitlines()[-1]
        == f"saved as a conformance case: {saved.relative_to(tmp_path)} (1 exchanges)"
    )
    assert tuple(load_session(saved).events) == tuple(load_session(session).events)


def test_proxy_refuses_before_opening_anything(tmp_path: Path) -> None:
    (tmp_path / "s.jsonl").write_text("evidence\n")
    base = ["proxy", "--real", str(tmp_path / "tty"), "--link", str(tmp_path / "link")]
    result = run(*base, "--device", "mp285", "--record", str(tmp_path / "s.jsonl"))
    assert (result.exit_code, result.stderr) == (
        1,
        f"stage-emu: {tmp_path}/s.jsonl: already exists; remove it or choose another file\n",
    )
    result = run(*base, "--device", "ms2000", "--profile", "mp285", "--record", str(tmp_path / "new.jsonl"))
    assert (result.exit_code, result.stderr) == (
        1,
        "stage-emu: profile mp285 is for the mp285, not the ms2000\n",
    )
    assert not (tmp_path / "link").exists()


def test_a_long_session_is_compared_as_it_is_read(tmp_path: Path) -> None:
    """The recording's exchanges come from the file a line at a time and meet the replay's one by
    one (before: the file and both sides were held whole, as lists)."""
    path = tmp_path / "long.jsonl"
    writes = 8000
    with path.open("w") as out:
        header = {"session": "stage-emu", "version": 1, "device": "ms2000", "profile": "ms2000"}
        out.write(
            json.dumps({**header, "line": {"baud": 9600, "data_bits": 8, "parity": "none", "stop_bits": 1}})
        )
        for i in range(writes):
            out.write(f'\n{{"t": {i * 0.01}, "dir": "rx", "hex": "2f 0d"}}')
            out.write(f'\n{{"t": {i * 0.01 + 0.005}, "dir": "tx", "hex": "4e 0d 0a"}}')
        out.write("\n")
    session = load_session(path)
    tracemalloc.start()
    try:
        compared, found = compare(
            "ms2000", iter_decode("ms2000", session.events), iter_decode("ms2000", session.events), TOLERANCE
        )
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert (compared, found) == (writes, [])
    assert peak < 2e6, f"{peak / 1e6:.1f} MB held"


def test_a_late_allowance_widens_only_the_late_side() -> None:
    """`late_allowance_s` (a test suite on a loaded machine): a reply may come that much later than
    the tolerance allows, never earlier."""
    want = Exchange(None, 0.0, pieces=[(0.010, b"\r")])
    late = Exchange(None, 0.0, pieces=[(0.500, b"\r")])
    early = Exchange(None, 0.0, pieces=[(-0.030, b"\r")])
    assert _timing(want, late, 0.030, late_allowance=1.0) == []
    assert _timing(want, late, 0.030) == [
        "first byte 490.0 ms late (tolerance 30 ms)",
        "last byte 490.0 ms late (tolerance 30 ms)",
    ]
    assert _timing(want, early, 0.030, late_allowance=1.0) == [
        "first byte 40.0 ms early (tolerance 30 ms)",
        "last byte 40.0 ms early (tolerance 30 ms)",
    ]
