"""Record and replay end to end: `stage-emu proxy` in front of a daemon's port (standing in for a
real controller), driven through its PTY by the host scripts of scripts/record_sessions.py, stopped
with SIGTERM; `stage-emu replay` of that session on the in-process emulator then reports no
difference, and one reply byte changed in the file makes it exit 1 naming that exchange. Bad input
(a live port's link, a port that does not exist, a malformed session) is one line, no traceback.

The replies are compared by their bytes (`--timing fast`). Their timing is the host's scheduling
twice over here (the recording went through the daemon's PTY and the proxy's, the replay runs in
process): tens of milliseconds apart on a loaded machine, which says nothing of the emulator. Timing
differences are checked on constructed sessions in tests/unit/test_replay.py, and recorded sessions
replay in time in tests/conformance/test_sessions.py."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from emulator.tools.session import TX, load_session
from scripts.record_sessions import record, running_proxy
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

TIMEOUT_S = 60.0


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    running = start_daemon(
        tmp_path_factory.mktemp("proxied"), ["--profile", "mp285", "--profile", "ms2000"], 2
    )
    yield running
    running.stop()


def stage_emu(*args: str) -> subprocess.CompletedProcess[str]:
    return finish(launch(*args))


def launch(*args: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "emulator.cli", *args]
    return subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen[str]) -> subprocess.CompletedProcess[str]:
    try:
        stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


def tamper(session: Path, family: str, out: Path) -> int:
    """Copy `session` to `out` with the first byte of the last position reply changed; its number."""
    request = "c" if family == "mp285" else "W X Y [WHERE]"
    exchanges = [e for e in load_session(session).exchanges() if e.request is not None]
    number, exchange = next(
        (i + 1, e)
        for i, e in reversed(list(enumerate(exchanges)))
        if e.request and e.request.summary == request
    )
    t, first = exchange.pieces[0]
    lines = session.read_text().splitlines()
    for index, line in enumerate(lines):
        record = json.loads(line)
        if record.get("dir") == TX and record["t"] == t:
            data = bytearray.fromhex(record["hex"])
            assert data.startswith(first)
            data[0] ^= 0x01
            lines[index] = json.dumps({**record, "hex": data.hex(" ")})
            break
    out.write_text("\n".join(lines) + "\n")
    return number


@pytest.mark.parametrize("family", ["mp285", "ms2000"])
def test_record_then_replay(daemon: RunningDaemon, tmp_path: Path, family: str) -> None:
    session = tmp_path / "session.jsonl"
    record(daemon.port(family), family, session)
    assert load_session(session).complete
    changed = tmp_path / "tampered.jsonl"
    number = tamper(session, family, changed)

    # both replays at once: each plays the session at its recorded times, mostly waiting
    as_recorded, tampered = (launch("replay", str(path), "--timing", "fast") for path in (session, changed))
    replayed = finish(as_recorded)
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert replayed.stdout.strip().endswith("no difference (timing not compared)")

    replayed = finish(tampered)
    assert replayed.returncode == 1, replayed.stdout + replayed.stderr
    diff, summary = replayed.stdout.splitlines()
    assert diff.startswith(f"#{number}  ") and diff.endswith("(reply bytes differ)")
    assert summary.startswith("1 of ")


def test_a_live_ports_link_is_refused(daemon: RunningDaemon, tmp_path: Path) -> None:
    link = daemon.port("mp285")
    result = stage_emu(
        "proxy",
        "--real",
        "stageemu://mp285",
        "--device",
        "mp285",
        "--link",
        link,
        "--record",
        str(tmp_path / "s.jsonl"),
    )
    assert result.returncode == 1
    assert result.stderr.startswith("stage-emu: ") and "still open" in result.stderr
    assert len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "s.jsonl").exists()


def test_a_second_proxy_on_the_same_link_is_refused(tmp_path: Path) -> None:
    link = tmp_path / "link"
    with running_proxy("stageemu://ms2000", "ms2000", link, tmp_path / "first.jsonl"):
        result = stage_emu(
            "proxy",
            "--real",
            "stageemu://ms2000",
            "--device",
            "ms2000",
            "--link",
            str(link),
            "--record",
            str(tmp_path / "second.jsonl"),
        )
    assert result.returncode == 1 and len(result.stderr.splitlines()) == 1
    assert "still open" in result.stderr


def test_a_real_port_that_cannot_be_opened(tmp_path: Path) -> None:
    missing = str(tmp_path / "ttyUSB9")
    result = stage_emu(
        "proxy",
        "--real",
        missing,
        "--device",
        "mp285",
        "--link",
        str(tmp_path / "link"),
        "--record",
        str(tmp_path / "s.jsonl"),
    )
    assert result.returncode == 1
    assert (
        result.stderr.startswith(f"stage-emu: cannot open {missing}") and len(result.stderr.splitlines()) == 1
    )
    assert not (tmp_path / "link").exists() and not (tmp_path / "s.jsonl").exists()
