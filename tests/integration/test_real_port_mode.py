"""The conformance suites' real-hardware switch (`--port PATH --device FAMILY`), exercised against an
emulator port standing in for the controller: the suites must run with no control channel, skip what
needs one, and bring a device left in any state back to the vectors' starting point themselves."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.daemon import ROOT, start_daemon


@pytest.mark.parametrize(
    ("family", "suite"),
    [
        ("mp285", "tests/conformance/mp285/test_client.py"),
        ("ms2000", "tests/conformance/ms2000/test_client.py"),
    ],
)
def test_client_suite_runs_against_a_plain_port(tmp_path: Path, family: str, suite: str) -> None:
    daemon = start_daemon(tmp_path / "daemon", ["--profile", family], expect_ports=1)
    try:
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "pytest",
                "-q",
                "-p",
                "no:cacheprovider",
                suite,
                "--port",
                daemon.port(family),
                "--device",
                family,
            ],
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        daemon.stop()
    summary = result.stdout.strip().splitlines()[-1]
    assert result.returncode == 0, result.stdout[-3000:]
    assert " passed" in summary and "failed" not in summary, summary
