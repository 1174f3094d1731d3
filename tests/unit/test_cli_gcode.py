"""`stage-emu gcode` without a controller: planning (`--dry-run`) and the one-line errors for a bad
program, a missing file or a missing port (MS-TRACER-5)."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import gcode as cli_gcode
from emulator.cli import main


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, ["gcode", *args])
    return result.exit_code, result.stdout, result.stderr


def test_dry_run_prints_the_plan(tmp_path: Path) -> None:
    program = tmp_path / "p.nc"
    program.write_text("G21 G90\nG01 X1 F60\nM03\nG04 P100\nM05\nG00 X0\n")
    code, out, _ = run(str(program), "--dry-run", "--speed-scale", "2")
    assert code == 0
    assert out.splitlines() == [
        "line 2: move X=1.000000 at 2.000000 mm/s",
        "line 3: TTL output on (M03)",
        "line 4: dwell 100 ms",
        "line 5: TTL output off (M05)",
        "line 6: move X=0.000000 rapid",
    ]


def test_bad_line_is_named_before_the_port_is_opened(tmp_path: Path) -> None:
    """The program is checked first: the port given here does not exist and is never opened."""
    program = tmp_path / "bad.nc"
    program.write_text("G21\nG01 X1 F60\nG01 X2 Q7\n")
    code, out, err = run(str(program), "--port", str(tmp_path / "no-port"))
    assert (code, out) == (1, "")
    assert err == f"stage-emu: {program}:3: Q7: unsupported\n"


def test_run_time_errors_name_the_line_too(tmp_path: Path) -> None:
    program = tmp_path / "arc.nc"
    program.write_text("G21\nG01 X1 F60\nG02 X3 R0.5\n")
    code, _, err = run(str(program), "--dry-run")
    assert code == 1
    assert err.startswith(f"stage-emu: {program}:3: radius R0.5 is too small")


def test_missing_file_port_and_bad_scale(tmp_path: Path) -> None:
    missing = tmp_path / "none.nc"
    assert run(str(missing), "--dry-run")[2] == f"stage-emu: {missing}: no such file\n"
    program = tmp_path / "p.nc"
    program.write_text("G00 X1\n")
    assert run(str(program))[2] == "stage-emu: --port PATH is required (or --dry-run to only plan)\n"
    code, _, err = run(str(program), "--port", str(tmp_path / "no-port"))
    assert code == 1 and err.startswith(f"stage-emu: {tmp_path / 'no-port'}: cannot open the port: ")
    code, _, err = run(str(program), "--dry-run", "--xyz-scale", "0")
    assert code == 2 and "'0' must be a number above 0" in err
    for _, _, err in (run(str(missing), "--dry-run"), run(str(program), "--port", "/nonexistent")):
        assert "Traceback" not in err


def test_dry_run_prints_the_plan_as_it_is_made(tmp_path: Path) -> None:
    """The program is read and planned a line at a time (before, a 2 M-move file passed 1.67 GB):
    the steps before a bad line are out when it is found."""
    program = tmp_path / "p.nc"
    program.write_text("G21 G90\nG01 X1 F60\nX2\nG01 X3 Q7\nX4\n")
    code, out, err = run(str(program), "--dry-run")
    assert code == 1 and err == f"stage-emu: {program}:4: Q7: unsupported\n"
    assert out.splitlines() == [
        "line 2: move X=1.000000 at 1.000000 mm/s",
        "line 3: move X=2.000000 at 1.000000 mm/s",
    ]


def test_a_last_line_without_its_newline_is_run_and_a_long_line_refused(tmp_path: Path) -> None:
    program = tmp_path / "p.nc"
    program.write_text("G01 X1 F60\nX2")
    assert run(str(program), "--dry-run")[1].splitlines()[-1] == "line 2: move X=2.000000 at 1.000000 mm/s"
    program.write_text("G01 X1 F60\n(" + "x" * 70_000 + ")\n")
    code, _, err = run(str(program), "--dry-run")
    assert (code, err) == (1, f"stage-emu: {program}:2: a line longer than 64 KiB, not a G-code program\n")


def test_an_interrupted_dry_run_claims_no_halt(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A dry run sends nothing, so Ctrl-C there halts no program and switches no TTL output off."""

    def interrupted(_steps: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_gcode, "_print_plan", interrupted)
    program = tmp_path / "p.nc"
    program.write_text("G01 X1 F60\n")
    assert run(str(program), "--dry-run") == (1, "", "stage-emu: interrupted\n")
