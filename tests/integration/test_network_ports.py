"""A daemon serving a device over RFC 2217 (`serve --profile F --rfc2217 127.0.0.1:0`) passes the
conformance suites in hardware mode (`--port rfc2217://...`), including the MP-285 parity vector
TV-4 that a PTY cannot carry. To keep the runtime modest (pyserial's RFC 2217 client costs ~0.7 s
per open and close) the suites run a subset: the client sessions and the line vectors (~50 s in all);
`pytest tests/conformance --port rfc2217://... --device F` runs them whole."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.daemon import ROOT, start_daemon

SUITES = {
    "mp285": ["tests/conformance/mp285/test_client.py", "tests/conformance/mp285/test_tv_line.py"],
    "ms2000": ["tests/conformance/ms2000/test_client.py", "tests/conformance/ms2000/test_line.py"],
}


@pytest.mark.parametrize("family", sorted(SUITES))
def test_conformance_subset_runs_over_rfc2217(tmp_path: Path, family: str) -> None:
    daemon = start_daemon(
        tmp_path / "daemon", ["--profile", family, "--rfc2217", "127.0.0.1:0"], expect_ports=1
    )
    url = daemon.port(family)
    assert url.startswith("rfc2217://127.0.0.1:") and daemon.ports[0]["transport"] == "rfc2217"
    assert daemon.control().list()[0]["ports"][0]["path"] == url
    try:
        hardware_mode = ["--port", url, "--device", family, "-W", "ignore::DeprecationWarning"]
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "pytest",
                "-q",
                "-rs",
                "-p",
                "no:cacheprovider",
                *SUITES[family],
                *hardware_mode,
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
    if family == "mp285":  # TV-4 runs: no "cannot carry parity" skip
        assert "cannot carry parity" not in result.stdout


def test_a_taken_address_is_one_line_and_exit_1(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RuntimeError, match=r"daemon exited \(1\)") as failure:
            start_daemon(tmp_path, ["--profile", "ms2000", "--tcp", f"127.0.0.1:{port}"], expect_ports=1)
    assert f"tcp port 127.0.0.1:{port}: cannot listen" in str(failure.value)
    assert not (tmp_path / "control.sock").exists()  # nothing half-created is left behind
