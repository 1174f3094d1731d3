"""A daemon serving a device over RFC 2217 (`serve --profile F --rfc2217 127.0.0.1:0`) passes the
whole conformance suite in hardware mode (`pytest tests/conformance --port rfc2217://... --device
F`), including the vectors a PTY cannot carry (MP-285 TV-4, MS2000 TV-120 on the wire: parity). The
suites run in the background of the session (tests/integration/conftest.py); these tests, run last,
check the outcome: nothing failed, and every skip has a reason a network port cannot help (the test
is for the other controller, or needs the control channel, timing only the emulator guarantees,
another profile, or a third-party driver that opens device paths only). Also: an address in use.
"""

from __future__ import annotations

import re
import socket
import xml.etree.ElementTree as ElementTree
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from tests.support.daemon import start_daemon

if TYPE_CHECKING:
    from tests.integration.conftest import Rfc2217Suites

#: what a skip over RFC 2217 may say (tests/conftest.py, tests/conformance/conftest.py)
SKIP_REASONS = re.compile(
    r"needs the emulator \((control|timing)(, timing)?\); running on a real port"
    r"|needs emulator profile .+"
    r"|python-microscope's driver opens a device path .+"
    r"|suite for another controller than --device \w+|test for \w+, port has \w+"
)
#: tests that must pass there, not skip: parity, which only a network or a real port carries
MUST_PASS = {
    "mp285": ("test_tv_004_parity_host_gets_a_frame_error",),
    "ms2000": ("test_tv_120_data_bits_and_parity_on_the_wire",),
}


@pytest.mark.parametrize("family", sorted(MUST_PASS))
def test_conformance_suite_runs_over_rfc2217(rfc2217_suites: Rfc2217Suites, family: str) -> None:
    run = rfc2217_suites.runs.get(family)
    assert run is not None, rfc2217_suites.failed[family]
    url = run.daemon.port(family)
    assert url.startswith("rfc2217://127.0.0.1:") and run.daemon.ports[0]["transport"] == "rfc2217"
    assert run.daemon.control().list()[0]["ports"][0]["path"] == url
    assert run.wait() == 0, run.report()
    outcomes: dict[str, str] = {}
    for case in ElementTree.parse(run.junit).iter("testcase"):
        skipped = case.find("skipped")
        name = case.get("name", "")
        if skipped is not None:
            reason = skipped.get("message", "")
            assert SKIP_REASONS.fullmatch(reason), f"{name} skipped over RFC 2217: {reason}"
        outcomes[name] = "skipped" if skipped is not None else "passed"
    for wanted in MUST_PASS[family]:
        ran = [outcome for name, outcome in outcomes.items() if name.split("[")[0] == wanted]
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
