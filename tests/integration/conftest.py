"""The conformance suites over RFC 2217, run in the background of the session.

Each family's whole suite (tests/conformance, as `pytest tests/conformance --port rfc2217://...
--device F` runs it) in hardware mode through a daemon's RFC 2217 port takes minutes of wall
time (device time passes in real time there: TV-21 alone is a 62.65 s move) but seconds of CPU. So
each starts as soon as collection ends, in its own pytest process against its own daemon
(`serve --profile F --rfc2217 127.0.0.1:0`), and runs while the rest of the session does; the tests
that take its outcome (fixture `rfc2217_suites`, test_network_ports.py) are moved to the end of the
session. Nothing starts unless one of them was selected, nor when the session itself runs against a
real port (`--port`).
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

from tests.support.daemon import ROOT, RunningDaemon, start_daemon

FIXTURE = "rfc2217_suites"
#: a suite that has not finished this long after it started has hung
SUITE_TIMEOUT_S = 900.0


@dataclass
class SuiteRun:
    """One family's suite: its daemon, the pytest process, and what that process writes."""

    family: str
    daemon: RunningDaemon
    proc: subprocess.Popen[bytes]
    output: Path
    junit: Path
    started: float
    #: wall seconds from start to exit (None while it runs)
    seconds: float | None = None

    def wait(self) -> int:
        """The pytest process's exit status once it has exited; then the daemon is stopped."""
        if self.seconds is None:
            left = self.started + SUITE_TIMEOUT_S - time.monotonic()
            try:
                self.proc.wait(max(left, 0.0))
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.seconds = time.monotonic() - self.started
            self.daemon.stop()
        return self.proc.returncode

    def report(self) -> str:
        """The end of the suite's output and of the daemon's log, for a failure message."""
        return f"{self.output.read_text()[-6000:]}\n--- daemon log ---\n{self.daemon.stderr()[-3000:]}"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self.daemon.stop()


class Rfc2217Suites:
    """The families' suite runs of this session, in a scratch directory of their own."""

    def __init__(self) -> None:
        self.workdir = Path(tempfile.mkdtemp(prefix="stage-emu-rfc2217-"))
        self.runs: dict[str, SuiteRun] = {}
        #: why a family's run did not start (reported by its test, not as an error of the session)
        self.failed: dict[str, str] = {}

    def start(self, family: str) -> None:
        try:
            daemon = start_daemon(
                self.workdir / family / "daemon",
                ["--profile", family, "--rfc2217", "127.0.0.1:0"],
                expect_ports=1,
            )
        except (OSError, RuntimeError) as exc:  # TimeoutError is an OSError
            self.failed[family] = f"the daemon did not start: {exc}"
            return
        self.runs[family] = self._run_suite(family, daemon)

    def _run_suite(self, family: str, daemon: RunningDaemon) -> SuiteRun:
        workdir = self.workdir / family
        url = daemon.port(family)
        output, junit = workdir / "pytest.out", workdir / "junit.xml"
        command = [
            *(sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider"),
            *("tests/conformance", "--port", url, "--device", family),
            *("--basetemp", str(workdir / "tmp"), "--junitxml", str(junit)),
            *("-W", "ignore::DeprecationWarning"),  # pyserial's RFC 2217 client calls Thread.setDaemon
        ]
        with open(output, "wb") as sink:
            proc = subprocess.Popen(
                command,
                cwd=ROOT,
                env={**os.environ, "PYTHONPATH": str(ROOT)},
                stdout=sink,
                stderr=subprocess.STDOUT,
            )
        return SuiteRun(family, daemon, proc, output, junit, time.monotonic())

    def stop(self) -> None:
        for run in self.runs.values():
            run.stop()
        shutil.rmtree(self.workdir, ignore_errors=True)


_suites: Rfc2217Suites | None = None


def _family(item: pytest.Item) -> str | None:
    """The family whose suite run `item` takes the outcome of (None: it takes none)."""
    if isinstance(item, pytest.Function) and FIXTURE in item.fixturenames:
        return str(item.callspec.params["family"])
    return None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: _family(item) is not None)  # stable: those last, the rest in order


def pytest_collection_finish(session: pytest.Session) -> None:
    global _suites
    if session.config.getoption("--port") or session.config.getoption("collectonly"):
        return
    families = sorted({family for item in session.items if (family := _family(item)) is not None})
    if families:
        _suites = Rfc2217Suites()
        for family in families:
            _suites.start(family)


def pytest_sessionfinish() -> None:
    if _suites is not None:
        _suites.stop()


@pytest.fixture(scope="session")
def rfc2217_suites() -> Rfc2217Suites:
    """The suite runs started when collection ended."""
    assert _suites is not None, "no suite was started: are the tests parametrized by `family`?"
    return _suites
