"""The conformance suites' smoke samples in real time, run in the background of the session.

The session itself runs tests/conformance in virtual time (the device in process: seconds for
both families). What virtual time cannot show is the same vectors end to end through the
transports a host program meets, in real time: so each family's fixed smoke sample
(`@pytest.mark.smoke`: framing, pacing, character timing, errors, a control-channel use, and the
family's recorded sessions) also runs over a daemon's RFC 2217 port in hardware mode
(`pytest tests/conformance/F -m smoke --port rfc2217://... --device F`, against
`serve --profile F --rfc2217 127.0.0.1:0`), over the pseudo-terminals of a daemon pool
(`pytest tests/conformance/F -m smoke --target daemon`), and over a daemon pool's serial ports on
null-modem cables of two pseudo-terminals (`--target serial`). Each run takes some seconds of wall time
(device time passes in real time) but little CPU, so each starts early, in its own pytest process,
and runs while the rest of the session does (fixture `smoke_runs`, test_network_ports.py, says how
in one process and under pytest-xdist). Nothing starts
unless one of them was selected, nor when the session itself runs against a real port (`--port`).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conformance.test_sessions import session_id
from tests.support.daemon import ROOT, RunningDaemon, start_daemon
from tests.support.process_group import end_group, start_group

FIXTURE = "smoke_runs"
#: the transports a smoke sample runs over: a daemon's RFC 2217 port, a daemon pool's PTYs, a
#: daemon pool's serial ports (each on a null-modem cable, tests/support/nullmodem.py)
RFC2217, PTY, SERIAL = "rfc2217", "pty", "serial"
#: a run that has not finished this long after it started has hung
RUN_TIMEOUT_S = 300.0
#: how long a run being ended may take to stop its daemons before all of it is killed
END_GRACE_S = 10.0


@dataclass
class SmokeRun:
    """One family's smoke sample over one transport: the pytest process, what it writes, and the
    daemon whose RFC 2217 port it talks to (None over PTYs: that run starts its own daemons)."""

    family: str
    transport: str
    daemon: RunningDaemon | None
    proc: subprocess.Popen[bytes]
    output: Path
    junit: Path
    started: float
    #: wall seconds from start to exit (None while it runs)
    seconds: float | None = None

    def wait(self) -> int:
        """The pytest process's exit status once it has exited; then the daemon is stopped."""
        if self.seconds is None:
            left = self.started + RUN_TIMEOUT_S - time.monotonic()
            try:
                self.proc.wait(max(left, 0.0))
            except subprocess.TimeoutExpired:
                end_group(self.proc, END_GRACE_S)
            self.seconds = time.monotonic() - self.started
            if self.daemon is not None:
                self.daemon.stop()
        return self.proc.returncode

    def report(self) -> str:
        """The end of the run's output and of the daemon's log, for a failure message."""
        log = "" if self.daemon is None else f"\n--- daemon log ---\n{self.daemon.stderr()[-3000:]}"
        return f"{self.output.read_text()[-6000:]}{log}"

    def stop(self) -> None:
        end_group(self.proc, END_GRACE_S)
        self.proc.wait()
        if self.daemon is not None:
            self.daemon.stop()


class SmokeRuns:
    """The smoke runs of this session, in a scratch directory of their own."""

    def __init__(self) -> None:
        self.workdir = Path(tempfile.mkdtemp(prefix="stage-emu-smoke-"))
        self.runs: dict[tuple[str, str], SmokeRun] = {}
        #: why a run did not start (reported by its test, not as an error of the session)
        self.failed: dict[tuple[str, str], str] = {}

    def start(self, family: str, transport: str) -> None:
        workdir = self.workdir / f"{family}-{transport}"
        args = ["--target", SERIAL if transport == SERIAL else "daemon"]
        daemon = None
        if transport == RFC2217:
            try:
                daemon = start_daemon(
                    workdir / "daemon", ["--profile", family, "--rfc2217", "127.0.0.1:0"], expect_ports=1
                )
            except (OSError, RuntimeError) as exc:  # TimeoutError is an OSError
                self.failed[family, transport] = f"the daemon did not start: {exc}"
                return
            args = ["--port", daemon.port(family), "--device", family]
        self.runs[family, transport] = self._run(family, transport, workdir, daemon, args)

    def _run(
        self, family: str, transport: str, workdir: Path, daemon: RunningDaemon | None, args: list[str]
    ) -> SmokeRun:
        workdir.mkdir(parents=True, exist_ok=True)
        output, junit = workdir / "pytest.out", workdir / "junit.xml"
        command = [
            *(sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider"),
            *(f"tests/conformance/{family}", *sessions_of(family), "-m", "smoke", *args),
            *("--basetemp", str(workdir / "tmp"), "--junitxml", str(junit)),
            *("-W", "ignore::DeprecationWarning"),  # pyserial's RFC 2217 client calls Thread.setDaemon
        ]
        with open(output, "wb") as sink:
            proc = start_group(
                command,
                cwd=ROOT,
                env={**os.environ, "PYTHONPATH": str(ROOT)},
                stdout=sink,
                stderr=subprocess.STDOUT,
            )
        return SmokeRun(family, transport, daemon, proc, output, junit, time.monotonic())

    def stop(self) -> None:
        for run in self.runs.values():
            run.stop()
        shutil.rmtree(self.workdir, ignore_errors=True)


def sessions_of(family: str) -> list[str]:
    """The test ids of the family's recorded sessions (tests/conformance/test_sessions.py)."""
    sessions = sorted((ROOT / "tests" / "conformance" / family / "sessions").glob("*.jsonl"))
    return [
        f"tests/conformance/test_sessions.py::test_session_replays[{session_id(path)}]" for path in sessions
    ]


_runs: SmokeRuns | None = None


def _run_of(item: pytest.Item) -> tuple[str, str] | None:
    """The (family, transport) whose smoke run `item` takes the outcome of (None: it takes none)."""
    if isinstance(item, pytest.Function) and FIXTURE in item.fixturenames:
        return str(item.callspec.params["family"]), str(item.callspec.params["transport"])
    return None


def _under_xdist(config: pytest.Config) -> bool:
    """Whether this process is a pytest-xdist worker (`make test` runs the session on every CPU)."""
    return hasattr(config, "workerinput")


# first: pytest-xdist's worker reads the group marks in its own hook, which otherwise runs before
# this one and left the smoke tests ungrouped (every worker that drew one started all six runs)
@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # In one process the runs start when collection ends and their tests go last, so the session's
    # own tests overlap them. Under xdist every worker collects everything and none can tell which
    # will get those tests: they form one group (`xdist_group`), go first, and start the runs in
    # the worker that takes the group, while the other workers go on with the rest.
    first = _under_xdist(config)
    items.sort(key=lambda item: (_run_of(item) is not None) != first)  # stable: the rest in order
    for item in items:
        if _run_of(item) is not None:
            item.add_marker(pytest.mark.xdist_group(FIXTURE))


def pytest_collection_finish(session: pytest.Session) -> None:
    if not _under_xdist(session.config):
        _start_wanted(session)


def _start_wanted(session: pytest.Session) -> None:
    global _runs
    if session.config.getoption("--port") or session.config.getoption("collectonly"):
        return
    wanted = sorted({run for item in session.items if (run := _run_of(item)) is not None})
    if wanted:
        _runs = SmokeRuns()
        for family, transport in wanted:
            _runs.start(family, transport)


def pytest_sessionfinish() -> None:
    if _runs is not None:
        _runs.stop()


@pytest.fixture(scope="session")
def smoke_runs(request: pytest.FixtureRequest) -> SmokeRuns:
    """The smoke runs, started when collection ended (or, under xdist, by their first test)."""
    if _runs is None and _under_xdist(request.config):
        grouped = [item.nodeid.endswith(f"@{FIXTURE}") for item in request.session.items if _run_of(item)]
        if request.config.getvalue("loadgroup") and not all(grouped):
            pytest.fail(
                "pytest-xdist did not keep the smoke tests on one worker (with pytest 9.2, pytest-xdist "
                "issue 1386): each worker that drew one would start every run; use pytest < 9.2"
            )
        _start_wanted(request.session)
    assert _runs is not None, "no smoke run was started: are the tests parametrized by `family`?"
    return _runs
