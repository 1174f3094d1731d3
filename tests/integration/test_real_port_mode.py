"""The conformance suites' real-hardware switch (`--port PATH --device FAMILY`), exercised against an
emulator port standing in for the controller: the suites must run with no control channel, skip what
needs one, and bring a device left in any state back to the vectors' starting point themselves.

Both families' suites start together, each in its own pytest process against its own daemon: they
spend their time waiting on device time passing in real time, so side by side they cost no more
than the longer one.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from tests.support.daemon import ROOT, RunningDaemon, start_daemon

SUITES = {
    "mp285": "tests/conformance/mp285/test_client.py",
    "ms2000": "tests/conformance/ms2000/test_client.py",
}
#: generous: a suite still running after this has hung
SUITE_TIMEOUT_S = 300.0


@dataclass
class SuiteRun:
    daemon: RunningDaemon
    proc: subprocess.Popen[str]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, SuiteRun]]:
    """Every family's client suite against a plain port of its own daemon, started at once."""
    started: dict[str, SuiteRun] = {}
    try:
        for family, suite in SUITES.items():
            workdir = tmp_path_factory.mktemp(family)
            daemon = start_daemon(workdir, ["--profile", family], expect_ports=1)
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", suite]
            command += ["--port", daemon.port(family), "--device", family]
            command += ["--basetemp", str(workdir / "tmp")]
            try:
                proc = subprocess.Popen(
                    command,
                    cwd=ROOT,
                    env={**os.environ, "PYTHONPATH": str(ROOT)},
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    text=True,
                )
            except BaseException:
                daemon.stop()
                raise
            started[family] = SuiteRun(daemon, proc)
        yield started
    finally:
        for run in started.values():
            if run.proc.poll() is None:
                run.proc.kill()
            run.proc.communicate()
            run.daemon.stop()


@pytest.mark.parametrize("family", sorted(SUITES))
def test_client_suite_runs_against_a_plain_port(runs: dict[str, SuiteRun], family: str) -> None:
    run = runs[family]
    output, errors = run.proc.communicate(timeout=SUITE_TIMEOUT_S)
    summary = output.strip().splitlines()[-1] if output.strip() else errors
    assert run.proc.returncode == 0, output[-3000:] + errors[-2000:]
    assert " passed" in summary and "failed" not in summary, summary
