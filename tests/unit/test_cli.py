"""The command line: validate, describe, profiles, serve argument errors, ctl without a daemon."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from emulator.cli import main
from emulator.profile import bundled_dir, display_path
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)


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


def test_validate_reads_through_the_profile_reader(tmp_path: Path) -> None:
    """A directory, a missing file and non-UTF-8 bytes: each its own line, exit 1, no traceback."""
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes(b"spec: 1\ndevice: probe\ndescription: caf\xe9\n")
    code, _, err = run("validate", str(tmp_path), str(tmp_path / "none.yaml"), str(latin1))
    assert code == 1
    assert err.splitlines() == [
        f"{tmp_path}: is a directory, not a file",
        f"{tmp_path / 'none.yaml'}: does not exist",
        f"{latin1}:3: not UTF-8 text, byte 38",
    ]


def test_describe_a_rig_names_its_profiles() -> None:
    rig = bundled_dir() / "rig.yaml"
    hint = "is a rig, not a profile; describe one of its profiles: mp285, ms2000"
    for ref in (str(rig), "rig"):
        code, _, err = run("describe", ref)
        assert (code, err.strip()) == (1, f"stage-emu: {display_path(rig)} {hint}")


def test_describe_columns_stay_aligned_with_long_values() -> None:
    """The status template (95 characters) and list values must not push later columns."""
    code, out, _ = run("describe", "mp285")
    assert code == 0
    _, listing, _ = run("describe", "mp285", "--json")
    starts: list[set[int]] = [set(), set(), set()]
    for line, row in zip(out.splitlines()[1:], json.loads(listing), strict=True):
        default = row["default"] if str(row["default"]).startswith("(") else json.dumps(row["default"])
        at = len(row["path"])
        for column, cell in enumerate((json.dumps(row["value"]), f"default {default}", row["rule"])):
            at = line.index(cell, at)
            starts[column].add(at)
            at += len(cell)
    assert [len(s) for s in starts] == [1, 1, 1]


def test_profiles_lists_every_bundled_profile() -> None:
    code, out, _ = run("profiles")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert "mp285a-qr" in names and "rig" not in names
    assert len({line.index(" mp285 ") for line in out.splitlines() if " mp285 " in line}) == 1
