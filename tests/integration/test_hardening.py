"""The daemon under misuse: it never removes what it did not create, refuses bad paths and numbers
with one line, shuts down cleanly on every terminating signal, restarts after kill -9, and keeps
serving through resource exhaustion and a failing traffic log."""

from __future__ import annotations

import json
import os
import resource
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from emulator.control_client import ControlClient, ControlFailure
from tests.support.daemon import ROOT, RunningDaemon, start_daemon

PROBE = ROOT / "tests" / "support" / "probe.yaml"
CLI = [sys.executable, "-m", "tests.support.serve"]
#: generous: only a hang takes this long on any machine
HANG_S = 10.0
#: a command's whole run, its start included: generous, a loaded machine has taken ten seconds to
#: start a Python process
RUN_S = 60.0


def env(tmp_path: Path) -> dict[str, str]:
    """Run with a private runtime directory so owner records of other tests stay apart."""
    run = tmp_path / "run"
    run.mkdir(exist_ok=True, mode=0o700)
    return {**os.environ, "PYTHONPATH": str(ROOT), "XDG_RUNTIME_DIR": str(run)}


def serve(tmp_path: Path, *args: str, timeout: float = RUN_S) -> subprocess.CompletedProcess[str]:
    """A `serve` that is expected to fail at start."""
    return subprocess.run(
        [*CLI, "serve", "--profile", str(PROBE), *args],
        cwd=ROOT,
        env=env(tmp_path),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def probe(tmp_path: Path, *extra: str) -> RunningDaemon:
    return start_daemon(
        tmp_path, ["--profile", str(PROBE), *extra], expect_ports=1, test_devices=True, env=env(tmp_path)
    )


def one_line_error(result: subprocess.CompletedProcess[str], text: str) -> None:
    assert result.returncode == 1, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("stage-emu: ") and text in lines[0], lines[0]


def echo(path: str, text: str = "hi") -> bytes:
    with serial.Serial(path, 9600, timeout=HANG_S) as port:
        port.write(f"E {text}\r".encode())
        return port.read(len(text) + 1)


@pytest.mark.parametrize("kind", ["file", "symlink"])
def test_control_path_occupied_by_a_user_file_is_refused_and_kept(tmp_path: Path, kind: str) -> None:
    precious = tmp_path / "thesis.tex"
    precious.write_text("years of work")
    control = tmp_path / "control.sock"
    if kind == "file":
        control.write_text("years of work")
    else:
        control.symlink_to(precious)
    result = serve(tmp_path, "--control", str(control), "--link-dir", str(tmp_path / "links"))
    one_line_error(result, "not a socket; refusing to replace it")
    assert os.path.lexists(control) and precious.read_text() == "years of work"
    assert not (tmp_path / "links" / "probe").exists()


def test_failed_second_serve_leaves_the_first_daemons_socket_and_ready_file(tmp_path: Path) -> None:
    first = probe(tmp_path, "--ready-file", str(tmp_path / "ready.json"))
    try:
        # same control path: refused; same ready file (it is the first one's): refused too
        for args, text in (
            (["--control", str(first.control_path)], "in use by a running stage-emu"),
            (
                ["--control", str(tmp_path / "other.sock"), "--ready-file", str(tmp_path / "ready.json")],
                "belongs to a running stage-emu",
            ),
        ):
            result = serve(tmp_path, *args, "--link-dir", str(tmp_path / "links2"))
            one_line_error(result, text)
        assert first.control_path.exists() and (tmp_path / "ready.json").exists()
        assert first.control().list()[0]["device"] == "probe"
        assert echo(first.port("probe")) == b"hi\r"
    finally:
        assert first.stop() == 0
    assert not first.control_path.exists() and not (tmp_path / "ready.json").exists()


def test_ready_file_path_holding_a_user_file_is_refused(tmp_path: Path) -> None:
    notes = tmp_path / "notes.json"
    notes.write_text('{"mine": true}')
    result = serve(tmp_path, "--ready-file", str(notes), "--control", str(tmp_path / "c.sock"))
    one_line_error(result, "is not a stage-emu ready file")
    assert notes.read_text() == '{"mine": true}'


@pytest.mark.parametrize(
    ("option", "value", "text"),
    [
        ("--control", "missing/control.sock", "does not exist"),
        ("--ready-file", "missing/ready.json", "does not exist"),
        ("--log-traffic", "missing/traffic.jsonl", "does not exist"),
        ("--link-dir", "/proc/nope", "cannot create it"),
        ("--control", "x" * 120, "a Unix socket path holds at most 107"),
        ("--time-scale", "nan", "finite"),
        ("--time-scale", "inf", "finite"),
        ("--time-scale", "1e300", "between"),
    ],
)
def test_bad_paths_and_numbers_are_one_line_errors(
    tmp_path: Path, option: str, value: str, text: str
) -> None:
    if option != "--time-scale" and not value.startswith("/"):
        value = str(tmp_path / value)
    args = [option, value]
    if option != "--control":
        args += ["--control", str(tmp_path / "c.sock")]
    if option != "--link-dir":
        args += ["--link-dir", str(tmp_path / "links")]
    result = serve(tmp_path, *args)
    if option == "--time-scale":
        assert result.returncode == 2 and "Traceback" not in result.stderr  # click's usage error
        assert text in result.stderr
    else:
        one_line_error(result, text)
    assert not (tmp_path / "c.sock").exists()


def test_runtime_dir_that_is_a_regular_file_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "run").mkdir(mode=0o700)
    (tmp_path / "run" / "stage-emu").write_text("a file")
    result = serve(tmp_path)
    one_line_error(result, "exists and is not a directory")
    assert (tmp_path / "run" / "stage-emu").read_text() == "a file"


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGINT, signal.SIGTERM, signal.SIGQUIT])
def test_terminating_signals_shut_down_cleanly(tmp_path: Path, sig: signal.Signals) -> None:
    daemon = probe(tmp_path, "--ready-file", str(tmp_path / "ready.json"))
    link = Path(daemon.port("probe"))
    assert link.is_symlink()
    assert daemon.stop(sig) == 0
    assert not os.path.lexists(link)
    assert not daemon.control_path.exists() and not (tmp_path / "ready.json").exists()
    assert not list((tmp_path / "run" / "stage-emu" / "owners").iterdir())
    assert "Traceback" not in daemon.stderr()


def test_sigusr1_reopens_the_traffic_log_and_keeps_serving(tmp_path: Path) -> None:
    traffic = tmp_path / "traffic.jsonl"
    daemon = probe(tmp_path, "--log-traffic", str(traffic))
    try:
        assert echo(daemon.port("probe"), "one") == b"one\r"
        traffic.rename(tmp_path / "traffic.1.jsonl")  # log rotation
        said = len(daemon.stderr().splitlines())
        daemon.proc.send_signal(signal.SIGUSR1)
        assert daemon.log.wait_line("reopened", said, HANG_S) is not None, daemon.stderr()
        assert traffic.exists()
        assert echo(daemon.port("probe"), "two") == b"two\r"
        assert daemon.proc.poll() is None
    finally:
        assert daemon.stop() == 0
    records = [json.loads(line) for line in traffic.read_text().splitlines()]
    assert b"two" in bytes.fromhex(" ".join(r["hex"] for r in records if r["dir"] != "ev"))


def test_restart_after_kill_9_replaces_the_dead_daemons_links(tmp_path: Path) -> None:
    first = probe(tmp_path, "--ready-file", str(tmp_path / "ready.json"))
    link = Path(first.port("probe"))
    old_pts = os.readlink(link)
    first.stop(signal.SIGKILL)
    # an unrelated program now holds the pts number the dead daemon used: this test (the kernel hands
    # out the lowest free number) or, when tests run side by side, another one that took it first
    holders: list[tuple[int, int]] = []
    try:
        while not os.path.exists(old_pts) and len(holders) < 64:
            holders.append(os.openpty())
        assert os.path.exists(old_pts)
        second = probe(tmp_path, "--ready-file", str(tmp_path / "ready.json"))
        try:
            assert echo(second.port("probe")) == b"hi\r"
        finally:
            assert second.stop() == 0
        assert "left behind" in second.stderr()
    finally:
        for master, slave in holders:
            os.close(master)
            os.close(slave)


def test_failing_traffic_log_is_reported_once_and_devices_keep_answering(tmp_path: Path) -> None:
    daemon = probe(tmp_path, "--log-traffic", "/dev/full")
    try:
        for i in range(20):
            assert echo(daemon.port("probe"), f"m{i}") == f"m{i}\r".encode()
    finally:
        assert daemon.stop() == 0
    errors = [line for line in daemon.stderr().splitlines() if "traffic log" in line]
    assert len(errors) == 1 and "traffic logging stopped" in errors[0]


def test_running_out_of_descriptors_neither_floods_nor_wedges(tmp_path: Path) -> None:
    def low_limit() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (40, 40))

    daemon = start_daemon(
        tmp_path,
        ["--profile", str(PROBE)],
        expect_ports=1,
        test_devices=True,
        env=env(tmp_path),
        preexec_fn=low_limit,
    )
    try:
        hogs = []
        for _ in range(60):  # more connections than descriptors: accept() fails with EMFILE
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.connect(str(daemon.control_path))
            hogs.append(sock)
        with serial.Serial(daemon.port("probe"), 9600, timeout=HANG_S) as port:
            for i in range(5):  # the devices keep serving meanwhile
                port.write(f"E {i}\r".encode())
                assert port.read(2) == f"{i}\r".encode()
        for sock in hogs:
            sock.close()
        with ControlClient(daemon.control_path, timeout=10) as client:
            assert client.list()[0]["device"] == "probe"  # recovered once descriptors are free
    finally:
        assert daemon.stop() == 0
    stderr = daemon.stderr()
    assert "Traceback" not in stderr and len(stderr.splitlines()) < 10, stderr


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    """One probe daemon for the tests that only ask it things (and leave it as they found it)."""
    daemon = probe(tmp_path_factory.mktemp("plain"))
    yield daemon
    assert daemon.stop() == 0, daemon.stderr()


def test_control_channel_refuses_wedging_numbers(plain: RunningDaemon) -> None:
    with ControlClient(plain.control_path) as client:
        for request in ({"op": "clock", "scale": 1e300}, {"op": "step", "seconds": 1e300}):
            with pytest.raises(ControlFailure, match="must be between"):
                client.request(request)
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as raw:
            raw.connect(str(plain.control_path))
            raw.sendall(b'{"id": 1, "op": "clock", "scale": NaN}\n')
            assert "not a number JSON allows" in json.loads(raw.makefile().readline())["error"]
        with pytest.raises(ControlFailure, match="ms"):
            client.fault("probe", "latency")
        assert client.clock()["scale"] == 1.0
    assert echo(plain.port("probe")) == b"hi\r"


def test_list_shows_health_and_names_are_listed(plain: RunningDaemon) -> None:
    with ControlClient(plain.control_path) as client:
        device = client.list()[0]
        assert device["storage_error"] is None
        assert device["ports"][0]["stats"] == {"output_dropped": 0, "input_discarded": 0}
        assert client.names("probe") == {"inputs": ["say"], "observables": ["host", "lines"]}
    result = subprocess.run(
        [*CLI, "ctl", "--control", str(plain.control_path), "get", "probe"],
        cwd=ROOT,
        env=env(plain.workdir),
        capture_output=True,
        text=True,
        timeout=RUN_S,
    )
    assert result.returncode == 0 and json.loads(result.stdout)["observables"] == ["host", "lines"]
