"""`--log-traffic` never appends to a file that is not a traffic log: refused with one line at
start-up, and at a SIGUSR1 reopen reported once while the devices keep answering."""

from __future__ import annotations

import signal
from pathlib import Path

from tests.integration.test_hardening import echo, one_line_error, probe, serve


def test_serve_refuses_to_append_to_a_users_file(tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("meeting at 10\n")
    result = serve(tmp_path, "--log-traffic", str(notes))
    one_line_error(result, f"--log-traffic {notes}: cannot open: not a traffic log")
    assert notes.read_text() == "meeting at 10\n"


def test_sigusr1_onto_a_users_file_stops_logging_and_devices_keep_answering(tmp_path: Path) -> None:
    traffic = tmp_path / "traffic.jsonl"
    daemon = probe(tmp_path, "--log-traffic", str(traffic))
    try:
        assert echo(daemon.port("probe"), "one") == b"one\r"
        traffic.rename(tmp_path / "traffic.1.jsonl")
        traffic.write_text("meeting at 10\n")  # another program took the path meanwhile
        daemon.proc.send_signal(signal.SIGUSR1)
        told = daemon.log.wait_line("traffic log", 0, timeout=20)  # reopened, or refused
        assert told is not None and "cannot reopen: not a traffic log" in told[1], daemon.stderr()
        assert echo(daemon.port("probe"), "two") == b"two\r"
    finally:
        assert daemon.stop() == 0
    assert traffic.read_text() == "meeting at 10\n"
    errors = [line for line in daemon.stderr().splitlines() if "traffic log" in line]
    assert len(errors) == 1 and "cannot reopen: not a traffic log" in errors[0], errors
