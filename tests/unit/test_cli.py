"""The command line: validate, describe, profiles, serve argument errors, ctl without a daemon."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

import tests.support.probe_device  # noqa: F401  (registers the `probe` family)
from emulator.cli import main

PROBE = str(Path(__file__).parent.parent / "support" / "probe.yaml")


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_validate_ok_and_failures(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("spec: 1\ndevice: probe\nline:\n  baud: 14400\n")
    code, out, err = run("validate", PROBE, str(bad))
    assert code == 1
    assert f"{PROBE}: ok" in out
    assert f"{bad}:4: line.baud: 14400 is not one of 1200, 2400, 4800, 9600, 19200, 115200" in err
    assert "Traceback" not in err


def test_validate_checks_rig_files(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        f"spec: 1\ndevices:\n  - name: a\n    profile: {PROBE}\n    overrides: {{line: {{parity: mark}}}}\n"
    )
    code, _, err = run("validate", str(rig))
    assert code == 1
    assert f"{rig}:5: line.parity: 'mark' is not one of 'none', 'even', 'odd'" in err


def test_validate_rig_cross_checks(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        f"spec: 1\ndevices:\n  - {{name: a, profile: {PROBE}}}\n  - {{name: a, profile: {PROBE}}}\n"
    )
    code, _, err = run("validate", str(rig))
    assert (code, err.strip()) == (1, f"{rig}: device name 'a' is used twice")


def test_describe_prints_every_knob_with_rule() -> None:
    code, out, _ = run("describe", PROBE)
    assert code == 0
    assert out.splitlines()[0] == "probe (probe): test-only probe device at 9600 8N1"
    baud = next(line for line in out.splitlines() if line.startswith("line.baud"))
    assert "9600" in baud and "T-1" in baud and "device baud rate" in baud


def test_describe_unknown_profile_is_a_sentence() -> None:
    code, _, err = run("describe", "no-such-profile")
    assert code == 1
    assert err.startswith("stage-emu: no-such-profile: no such profile")


def test_serve_rejects_rig_and_profiles_together(tmp_path: Path) -> None:
    code, _, err = run("serve", str(tmp_path / "rig.yaml"), "--profile", PROBE)
    assert (code, err.strip()) == (1, "stage-emu: give either a rig file or --profile options, not both")


def test_serve_reports_bad_rig_without_traceback(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("spec: 1\ndevices: []\n")
    code, _, err = run("serve", str(rig))
    assert code == 1
    assert err.strip() == f"stage-emu: {rig}:2: devices: has 0 items, expected at least 1"


def test_ctl_without_daemon_says_so(tmp_path: Path) -> None:
    code, _, err = run("ctl", "--control", str(tmp_path / "none.sock"), "list")
    assert code == 1
    assert "cannot reach the daemon" in err and "is `stage-emu serve` running?" in err


def test_ctl_params_must_be_key_value(tmp_path: Path) -> None:
    code, _, err = run("ctl", "--control", str(tmp_path / "none.sock"), "input", "dev", "x", "novalue")
    assert (code, err.strip()) == (1, "stage-emu: expected key=value, got 'novalue'")


def test_describe_marks_only_values_that_differ_from_their_default(tmp_path: Path) -> None:
    changed = tmp_path / "changed.yaml"
    changed.write_text(f"spec: 1\nextends: {PROBE}\ndescription: a slower probe\nline: {{baud: 4800}}\n")
    code, out, _ = run("describe", str(changed))
    assert code == 0
    marked = [line.split()[0] for line in out.splitlines()[1:] if line.endswith("  *")]
    assert marked == ["line.baud"]
