"""`stage-emu gcode` against a served `ms2000-tracer` (MS-TRACER-5): a program runs to its end on
the emulator; a host at the wrong baud rate gets one clear line, not a traceback."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from protocols.clients import MS2000
from tests.support.daemon import RunningDaemon, start_daemon

DEVICE = "ms2000-tracer"
PROGRAM = """\
%
(a quarter circle traced with the output on)
G21 G90
G01 X0.5 F300
M03
G03 X0 Y0.5 I-0.5
M05
G04 P50
G00 X0 Y0
%
"""


#: device seconds per wall second: the program's 3.5 s of moves take a third of a second; the host
#: side (the executor's polls, its reply timeout) runs on the wall clock, whatever the scale
TIME_SCALE = "10"


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningDaemon]:
    args = ["--profile", DEVICE, "--time-scale", TIME_SCALE]
    served = start_daemon(tmp_path_factory.mktemp("gcode"), args, expect_ports=1)
    yield served
    served.stop()


def test_gcode_runs_a_program_on_the_served_emulator(daemon: RunningDaemon, tmp_path: Path) -> None:
    control = daemon.control()
    control.reset(DEVICE)
    program = tmp_path / "quarter.nc"
    program.write_text(PROGRAM)
    # a reply timeout only a hang reaches on a loaded machine (the default is 2 s)
    args = ["gcode", str(program), "--port", daemon.port(DEVICE), "--timeout", "10"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "counts per mm: X=45396 Y=45396 Z=20000"
    assert lines[-1].startswith("done: ") and "1 dwells, 2 output changes" in lines[-1]
    axes = control.get(DEVICE, "axes")
    assert (axes["X"]["user_mm"], axes["Y"]["user_mm"]) == (0.0, 0.0)
    assert control.get(DEVICE, "ttl_out0") == 0
    with MS2000(daemon.port(DEVICE), 115200, timeout=10) as stage:
        assert stage.get("S", "X", "Y") == {"X": 5.1456, "Y": 5.1456}  # restored after the run


def test_gcode_at_the_wrong_baud_rate_is_one_line(daemon: RunningDaemon, tmp_path: Path) -> None:
    """MS-TRACER-2, MS-4: at 9600 the 115200 controller hears only garble and answers nothing."""
    program = tmp_path / "line.nc"
    program.write_text("G01 X1 F60\n")
    port = daemon.port(DEVICE)
    args = ["gcode", str(program), "--port", port, "--baud", "9600", "--timeout", "0.3"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 1
    assert result.stderr.startswith(f"stage-emu: {port}: 'BU X': no complete reply within 0.3 s")
    assert "Traceback" not in result.stderr
