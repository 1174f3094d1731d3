"""`stage-emu capture` over a daemon's pseudo-terminals in real time: the captured profiles of a
non-default MS2000 and of an MP-285A match the served ones in every captured field, and the
devices received only the read-only commands `--dry-run` lists (their traffic on the control
channel)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.control_client import ControlClient
from emulator.tools.capture import LineOptions, capture
from emulator.tools.capture.mp285 import plan as mp285_plan
from emulator.tools.capture.ms2000 import plan as ms2000_plan
from tests.support.capture import mismatches, served_profile
from tests.support.daemon import RunningDaemon, start_daemon

MS2000_CHANGES: dict[str, Any] = {
    "version": "USB-9.2n",
    "axes": {"X": {"speed_mm_s": 3.5, "backlash_mm": 0.01}, "Z": {"accel_ms": 40}},
    "knobs": {"info_fix_pc_tag": True},
}
#: a reply timeout only a hang reaches on a loaded machine; the silent `I F` waits it out once
TIMEOUT = 3.0


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[RunningDaemon, Path]]:
    profiles = tmp_path_factory.mktemp("profiles")
    stage = served_profile(profiles, "ms2000-af", "lab-af", **MS2000_CHANGES)
    args = ["--profile", str(stage), "--profile", "mp285a"]
    daemon = start_daemon(tmp_path_factory.mktemp("capture"), args, expect_ports=2)
    yield daemon, stage
    daemon.stop()


def traffic_of(control: ControlClient, device: str) -> bytes:
    """What `device` received since the subscription, from its traffic records."""
    received = []
    for event in control.events(timeout=0.5):
        if event.get("ev") == "traffic" and event["device"] == device and event["dir"] == "rx":
            received.append(event["hex"])
    return bytes.fromhex(" ".join(received))


def test_the_ms2000_capture_reproduces_the_served_profile(
    served: tuple[RunningDaemon, Path], tmp_path: Path
) -> None:
    daemon, stage = served
    name = next(p["device"] for p in daemon.ports if p["profile"] == "lab-af")
    control = daemon.control()
    control.subscribe(name, traffic=True)
    result = capture(daemon.port(name), "ms2000", LineOptions(), TIMEOUT, "lab")
    assert traffic_of(control, name) == b"".join(q.wire for q in ms2000_plan())
    assert (result.settled.parent.name, result.notes) == ("ms2000-af", [])
    out = tmp_path / "lab.yaml"
    out.write_text(result.text)
    assert mismatches(result.settled.readings, stage, out) == []


def test_the_mp285a_capture_reproduces_the_served_profile(
    served: tuple[RunningDaemon, Path], tmp_path: Path
) -> None:
    daemon, _ = served
    control = daemon.control()
    control.subscribe("mp285a", traffic=True)
    out = tmp_path / "mp.yaml"
    port = daemon.port("mp285a")
    args = ["--device", "mp285", "--rtscts", "--port", port, "-o", str(out), "--timeout", str(TIMEOUT)]
    result = CliRunner().invoke(main, ["capture", *args])
    assert result.exit_code == 0, result.stderr
    assert "extends mp285a and sets 0 of them" in result.stderr
    assert traffic_of(control, "mp285a") == b"".join(q.wire for q in mp285_plan())
    captured = capture(port, "mp285", LineOptions(rtscts=True), TIMEOUT).settled
    assert mismatches(captured.readings, "mp285a", out) == []
