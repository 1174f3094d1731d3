"""Each family's smoke sample of the conformance suite (`@pytest.mark.smoke`) passes in real time
over a daemon's RFC 2217 port in hardware mode (`pytest tests/conformance/F -m smoke --port
rfc2217://... --device F` against `serve --profile F --rfc2217 127.0.0.1:0`), including the vectors
a PTY cannot carry (MP-285 TV-4, MS2000 TV-120 on the wire: parity), and over a daemon pool's
pseudo-terminals (`--target daemon`). The runs go in the background of the session
(tests/integration/conftest.py); these tests, run last, check the outcome: nothing failed, every
skip has a reason the transport cannot help (over RFC 2217: the test is for the other controller,
or needs the control channel, timing only the emulator guarantees, another profile, or a
third-party driver that opens device paths only; over a PTY: parity), and enough ran that the
sample was not lost. Also: an address in use.
"""

from __future__ import annotations

import re
import socket
import xml.etree.ElementTree as ElementTree
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from tests.conformance.conftest import NO_PARITY
from tests.integration.conftest import PTY, RFC2217
from tests.support.daemon import start_daemon

if TYPE_CHECKING:
    from tests.integration.conftest import SmokeRun, SmokeRuns

#: what a skip may say, per transport (tests/conftest.py, tests/conformance/conftest.py)
SKIP_REASONS = {
    RFC2217: re.compile(
        r"needs the emulator \((control|timing)(, timing)?\); running on a real port"
        r"|needs emulator profile .+"
        r"|python-microscope's driver opens a device path .+"
        r"|suite for another controller than --device \w+|test for \w+, port has \w+"
    ),
    PTY: re.compile(re.escape(NO_PARITY)),
}
#: tests that must pass over RFC 2217, not skip: parity, which only a network or a real port carries
MUST_PASS = {
    "mp285": ("test_tv_004_parity_host_gets_a_frame_error",),
    "ms2000": ("test_tv_120_data_bits_and_parity_on_the_wire",),
}
#: fewer passed tests than this means the sample was lost (a marker dropped, a module not collected)
MIN_PASSED = 5


def outcomes(run: SmokeRun) -> dict[str, str]:
    """Each test case's outcome by name, every skip's reason checked."""
    found: dict[str, str] = {}
    for case in ElementTree.parse(run.junit).iter("testcase"):
        skipped = case.find("skipped")
        name = f"{case.get('name', '')} ({case.get('classname', '')})"
        if skipped is not None:
            reason = skipped.get("message", "")
            assert SKIP_REASONS[run.transport].fullmatch(reason), (
                f"{name} skipped over {run.transport}: {reason}"
            )
        found[name] = "skipped" if skipped is not None else "passed"
    return found


@pytest.mark.parametrize("transport", [RFC2217, PTY])
@pytest.mark.parametrize("family", sorted(MUST_PASS))
def test_conformance_smoke_runs_in_real_time(smoke_runs: SmokeRuns, family: str, transport: str) -> None:
    run = smoke_runs.runs.get((family, transport))
    assert run is not None, smoke_runs.failed[family, transport]
    if run.daemon is not None:
        url = run.daemon.port(family)
        assert url.startswith("rfc2217://127.0.0.1:") and run.daemon.ports[0]["transport"] == "rfc2217"
        assert run.daemon.control().list()[0]["ports"][0]["path"] == url
    assert run.wait() == 0, run.report()
    found = outcomes(run)
    assert list(found.values()).count("passed") >= MIN_PASSED, (found, run.report())
    if transport == RFC2217:
        for wanted in MUST_PASS[family]:
            ran = [outcome for name, outcome in found.items() if re.split(r"[\[ ]", name)[0] == wanted]
            assert ran and set(ran) == {"passed"}, f"{wanted}: {ran}"


def test_a_taken_address_is_one_line_and_exit_1(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RuntimeError, match=r"daemon exited \(1\)") as failure:
            start_daemon(tmp_path, ["--profile", "ms2000", "--tcp", f"127.0.0.1:{port}"], expect_ports=1)
    assert f"tcp port 127.0.0.1:{port}: cannot listen" in str(failure.value)
    assert not (tmp_path / "control.sock").exists()  # nothing half-created is left behind
