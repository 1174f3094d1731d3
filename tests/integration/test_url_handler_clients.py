"""The client conformance suites run in-process through the `stageemu://` URL handler, as they run
against a real controller (`--port URL --device FAMILY`): no daemon, no pseudo-terminal. A test that
needs another profile or a knob gets a URL with that profile (tests/conformance/conftest.py); only
those needing the control channel skip.

The MS2000 suite runs at realistic timing: with `timing=fast` in-process, no device time at all
passes between two commands, so `test_halt`'s HALT right after a move starts finds the stage still at
the origin, and its following `M X=0` is no move to halt (the model is right; a real wire, or a
daemon's PTY latency, always lets a few milliseconds pass). The MP-285 suite needs no such interval
and runs at `timing=fast`.

Both suites start together, each in its own pytest process: they spend their time waiting on device
time passing in real time (seconds of wall time for a fraction of a second of CPU), so running them
side by side costs no more than the longer one.
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: family -> (URL, tests passed, tests skipped)
SUITES = {"mp285": ("stageemu://mp285?timing=fast", 4, 1), "ms2000": ("stageemu://ms2000", 6, 0)}
#: generous: a suite still running after this has hung
SUITE_TIMEOUT_S = 300.0


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, subprocess.Popen[str]]]:
    """Every family's suite, started at once (each with a temporary directory of its own)."""
    started = {}
    try:
        for family, (url, _, _) in SUITES.items():
            suite = f"tests/conformance/{family}/test_client.py"
            command = [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", suite]
            command += ["--basetemp", str(tmp_path_factory.mktemp(family))]
            started[family] = subprocess.Popen(
                [*command, "--port", url, "--device", family],
                cwd=ROOT,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        yield started
    finally:
        for proc in started.values():
            if proc.poll() is None:
                proc.kill()
            proc.communicate()


@pytest.mark.parametrize("family", sorted(SUITES))
def test_client_suite_through_the_url(runs: dict[str, subprocess.Popen[str]], family: str) -> None:
    _, passed, skipped = SUITES[family]
    stdout, stderr = runs[family].communicate(timeout=SUITE_TIMEOUT_S)
    summary = stdout.strip().splitlines()[-1] if stdout.strip() else stderr
    assert runs[family].returncode == 0, stdout[-4000:] + stderr[-2000:]
    assert re.search(rf"\b{passed} passed\b", summary) and "failed" not in summary, summary
    skips = re.findall(r"^SKIPPED \[(\d+)\] .*: (.*)$", stdout, re.MULTILINE)
    assert sum(int(count) for count, _ in skips) == skipped, stdout
    assert all(reason.startswith("needs the emulator (control)") for _, reason in skips), skips
