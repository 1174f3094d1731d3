"""`stage-emu capture` as a command: `--dry-run` opens nothing, the profile goes to stdout or to a new
file (mode 0600, never over an existing one without `--force`), and every failure is one line."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner, Result

from emulator.cli import main
from emulator.profiles.profile import load_profile
from emulator.urlhandler.url import VIRTUAL

MS2000 = f"stageemu://ms2000-crisp?time={VIRTUAL}"


def run(*args: str) -> Result:
    return CliRunner().invoke(main, ["capture", *args])


def test_dry_run_lists_the_commands_and_opens_no_port(tmp_path: Path) -> None:
    missing = str(tmp_path / "no-such-port")
    ms2000 = run("--dry-run", "--device", "ms2000", "--port", missing)
    assert ms2000.exit_code == 0, ms2000.output
    lines = [line for line in ms2000.stdout.splitlines() if not line.startswith("#")]
    assert lines[:5] == ["V", "BU X", "CD", "N", "SB X?"]
    assert "S X? Y? Z?" in lines and lines[-3:] == ["JS F?", "I F", "(empty line)"]
    mp285 = run("--dry-run", "--device", "mp285")
    assert mp285.exit_code == 0, mp285.output
    assert [line for line in mp285.stdout.splitlines() if not line.startswith("#")] == [
        "73 0D    s",
        "0D       CR",
    ]


def test_without_output_the_profile_goes_to_stdout_and_the_summary_to_stderr() -> None:
    result = run("--device", "ms2000", "--port", MS2000)
    assert result.exit_code == 0, result.stderr
    assert yaml.safe_load(result.stdout)["extends"] == "ms2000-crisp"
    assert result.stderr == (
        "stage-emu: 33 queries, 117 fields read; the profile extends ms2000-crisp and sets 1 of them\n"
    )


def test_the_file_is_new_and_private_and_never_overwritten_without_force(tmp_path: Path) -> None:
    out = tmp_path / "lab-stage.yaml"
    first = run("--device", "ms2000", "--port", MS2000, "-o", str(out))
    assert first.exit_code == 0, first.stderr
    assert stat.S_IMODE(out.stat().st_mode) == 0o600
    assert load_profile(str(out)).config.device_id == "lab-stage"
    out.write_text("my notes\n")
    again = run("--device", "ms2000", "--port", MS2000, "-o", str(out))
    assert (again.exit_code, again.stderr) == (1, f"stage-emu: {out} exists; --force to overwrite it\n")
    assert out.read_text() == "my notes\n"
    forced = run("--device", "ms2000", "--port", MS2000, "-o", str(out), "--force")
    assert forced.exit_code == 0, forced.stderr
    assert load_profile(str(out)).name == "lab-stage"
    assert stat.S_IMODE(out.stat().st_mode) == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lab-stage.yaml"], "no temporary file left"


def test_no_reply_to_the_first_query_is_one_line() -> None:
    """MS-2, MS-4: a 115200 build opened at 9600 hears garble and answers nothing."""
    port = f"stageemu://ms2000-ttlrep?time={VIRTUAL}"
    result = run("--device", "ms2000", "--port", port)
    assert result.exit_code == 1
    assert result.stderr == (
        f"stage-emu: {port}: no reply to V at 9600 8N1 within 1.08 s: wrong port, device or baud rate?\n"
    )
    assert run("--device", "ms2000", "--port", port, "--baud", "115200").exit_code == 0


def test_a_port_that_cannot_be_opened_is_one_line(tmp_path: Path) -> None:
    result = run("--device", "mp285", "--port", str(tmp_path / "ttyNone"))
    assert result.exit_code == 1
    assert result.stderr.startswith(f"stage-emu: {tmp_path / 'ttyNone'}: cannot open the port: ")
    assert len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--device", "ms2000"], "--port PORT is required"),
        (["--device", "ms2000", "--port", "x", "--rtscts"], "--rtscts: the MS2000 has no flow control"),
        (["--device", "ms2000", "--port", "x", "--baud", "4800"], "--baud 4800: the MS2000 runs at"),
        (["--device", "mp285", "--port", "x", "--rtscts", "--baud", "19200"], "fixed at 9600 8N1"),
        (["--device", "mp285", "--port", "x", "--timeout", "0"], "must be above 0"),
    ],
)
def test_bad_options_are_usage_errors(args: list[str], message: str) -> None:
    result = run(*args)
    assert result.exit_code == 2 and message in result.stderr, result.output
