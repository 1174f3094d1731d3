"""The pytest plugin (emulator/pytest_plugin.py) used the way a user would: a small host program and
its tests, run by pytest in a subprocess, against the emulator and against a "real" port (an
emulator port started here, with no control channel handed to the suite)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from emulator.hosting.launcher import start_daemon
from tests.support.daemon import ROOT

pytest_plugins = ["pytester"]

README = ROOT / "README.md"


def _readme_block(caption: str) -> str:
    """The README's code block right after the line `caption` (its pytest example, tested as is)."""
    text = README.read_text(encoding="utf-8")
    after = text.index(caption + "\n")
    block = re.search(r"```python\n(.*?)```", text[after:], re.DOTALL)
    assert block is not None, caption
    return block.group(1)


HOST_PROGRAM = _readme_block("The host program, `stage.py`:")
USER_TESTS = _readme_block("Its tests, `test_stage.py`:")
VIRTUAL_TESTS = _readme_block("Its test in virtual time, `test_stage_virtual.py`:")

# each test notes its daemon's pid, so the outer test can check that none outlives the run
LIFECYCLE_TESTS = """
from pathlib import Path


def note(kind, emu):
    with open("pids.txt", "a") as pids:
        pids.write(f"{kind} {emu.daemon.proc.pid}\\n")


def test_function_daemon_is_fresh(stage_emu):
    emu = stage_emu()
    note("function", emu)
    assert emu.control.get("ms2000", "axes")["X"]["machine_counts"] == 0


def test_failing_test_still_stops_its_daemon(stage_emu):
    note("function", stage_emu())
    assert False, "deliberate failure"


def test_rig_file_and_serve_options(stage_emu):
    emu = stage_emu(rig="rig.yaml", log_traffic="traffic.jsonl")
    note("function", emu)
    assert sorted(emu.ports) == ["stage", "stage.aux"]
    assert Path(emu.port("stage", "aux")).exists() and Path("traffic.jsonl").exists()


def test_session_daemon_first(stage_emu_session):
    emu = stage_emu_session(profiles=["ms2000"])
    note("session", emu)
    assert emu.control.get("ms2000", "busy") is False


def test_session_daemon_second(stage_emu_session):
    emu = stage_emu_session(profiles=["ms2000"])
    note("session", emu)
    assert Path(emu.port("ms2000")).exists()
"""


def _process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_user_suite_on_the_emulator_leaves_no_daemon(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(stage=HOST_PROGRAM, test_stage=USER_TESTS, test_lifecycle=LIFECYCLE_TESTS)
    # a TTL REPORT build: its auxiliary port is served beside the main one
    pytester.makefile(".yaml", rig='{"spec": 1, "devices": [{"name": "stage", "profile": "ms2000-ttlrep"}]}')
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", timeout=60)
    result.assert_outcomes(passed=6, failed=1)
    result.stdout.fnmatch_lines(["*deliberate failure*"])
    noted = [line.split() for line in (pytester.path / "pids.txt").read_text().splitlines()]
    function_pids = [int(pid) for kind, pid in noted if kind == "function"]
    session_pids = {int(pid) for kind, pid in noted if kind == "session"}
    assert len(set(function_pids)) == 3 and len(session_pids) == 1
    assert not [pid for pid in [*function_pids, *session_pids] if _process_exists(pid)]


@pytest.mark.parametrize("transport", [[], ["--rfc2217", "127.0.0.1:0"]], ids=["pty", "rfc2217"])
def test_real_port_switch_uses_the_port_and_skips_marked_tests(
    pytester: pytest.Pytester, tmp_path: Path, transport: list[str]
) -> None:
    # an emulator port standing in for a real controller: the suite gets only its path (or URL)
    hardware = start_daemon(tmp_path / "hardware", ["--profile", "ms2000", "--timing", "fast", *transport], 1)
    try:
        pytester.makepyfile(stage=HOST_PROGRAM, test_stage=USER_TESTS)
        port = hardware.port("ms2000")
        result = pytester.runpytest_subprocess(
            "-p",
            "no:cacheprovider",
            "-rs",
            "--stage-emu-port",
            port,
            "--stage-emu-device",
            "ms2000",
            timeout=60,
        )
        with hardware.control() as control:
            moved_to = control.get("ms2000", "axes")["X"]["position"]
    finally:
        hardware.stop()
    result.assert_outcomes(passed=1, skipped=1)
    result.stdout.fnmatch_lines([f"*needs the emulator's control channel; --stage-emu-port {port}*"])
    assert moved_to == "1000"  # the unmarked test drove the given port, not a daemon of its own


def test_real_port_without_device_name_is_a_usage_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_nothing="def test_nothing(): pass")
    result = pytester.runpytest_subprocess("--stage-emu-port", "/dev/null", timeout=60)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--stage-emu-port needs --stage-emu-device*"])


def test_the_virtual_time_example_runs_without_a_daemon(pytester: pytest.Pytester) -> None:
    """The README's virtual-time test as a user runs it: a 10 s move, passed in device time."""
    pytester.makepyfile(stage=HOST_PROGRAM, test_stage_virtual=VIRTUAL_TESTS)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", timeout=60)
    result.assert_outcomes(passed=1)


def test_the_virtual_time_example_is_skipped_on_a_real_port(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(stage=HOST_PROGRAM, test_stage_virtual=VIRTUAL_TESTS)
    result = pytester.runpytest_subprocess(
        "-p", "no:cacheprovider", "--stage-emu-port", "/dev/null", "--stage-emu-device", "ms2000", timeout=60
    )
    result.assert_outcomes(skipped=1)
