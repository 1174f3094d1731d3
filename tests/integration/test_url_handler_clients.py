"""The client conformance suites run in-process through the `stageemu://` URL handler, as they run
against a real controller (`--port URL --device FAMILY`): no daemon, no pseudo-terminal. A test that
needs another profile or a knob gets a URL with that profile (tests/conformance/conftest.py); only
those needing the control channel skip.

The MS2000 suite runs at realistic timing: with `timing=fast` in-process, no device time at all
passes between two commands, so `test_halt`'s HALT right after a move starts finds the stage still at
the origin, and its following `M X=0` is no move to halt (the model is right; a real wire, or a
daemon's PTY latency, always lets a few milliseconds pass). The MP-285 suite needs no such interval
and runs at `timing=fast`.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("family", "url", "passed", "skipped"),
    [("mp285", "stageemu://mp285?timing=fast", 4, 1), ("ms2000", "stageemu://ms2000", 6, 0)],
)
def test_client_suite_through_the_url(family: str, url: str, passed: int, skipped: int) -> None:
    suite = f"tests/conformance/{family}/test_client.py"
    command = [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", suite]
    result = subprocess.run(
        [*command, "--port", url, "--device", family],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    summary = result.stdout.strip().splitlines()[-1] if result.stdout.strip() else result.stderr
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert re.search(rf"\b{passed} passed\b", summary) and "failed" not in summary, summary
    skips = re.findall(r"^SKIPPED \[(\d+)\] .*: (.*)$", result.stdout, re.MULTILINE)
    assert sum(int(count) for count, _ in skips) == skipped, result.stdout
    assert all(reason.startswith("needs the emulator (control)") for _, reason in skips), skips
