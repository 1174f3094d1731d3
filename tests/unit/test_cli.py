"""The command line: validate, describe, profiles, serve argument errors, ctl without a daemon."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.device import DeviceServices
from emulator.profiles import registry
from emulator.profiles.profile import MAX_PROBLEMS, bundled_dir, bundled_names, display_path, load_profile
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
    assert (code, err.strip()) == (1, f"{rig}:4: devices[1]: device name 'a' is used twice")


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
    starts: list[set[int]] = [set(), set(), set(), set()]
    for line, row in zip(out.splitlines()[1:], json.loads(listing), strict=True):
        default = row["default"] if str(row["default"]).startswith("(") else json.dumps(row["default"])
        at = len(row["path"])
        cells = (json.dumps(row["value"]), f"default {default}", f"allowed {row['type']}", row["rule"])
        for column, cell in enumerate(cells):
            at = line.index(cell, at)
            starts[column].add(at)
            at += len(cell)
    assert [len(s) for s in starts] == [1, 1, 1, 1]


def test_profiles_lists_every_bundled_profile() -> None:
    code, out, _ = run("profiles")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert "mp285a-qr" in names and "rig" not in names
    assert len({line.index(" mp285 ") for line in out.splitlines() if " mp285 " in line}) == 1


def every_bundled_name(kind: str) -> tuple[dict[str, set[str]], dict[str, str]]:
    """Each name of `kind` a bundled profile's model accepts, with the profiles that accept it; and
    each bundled profile's family."""
    found: dict[str, set[str]] = {}
    families: dict[str, str] = {}
    for name in bundled_names():
        profile = load_profile(name)
        family = registry.family(profile.family)
        assert family is not None
        families[name] = profile.family
        for item in family.factory(name, profile, 0.0, DeviceServices()).control_names()[kind]:
            found.setdefault(item, set()).add(name)
    return found, families


@pytest.mark.parametrize(("command", "kind"), [("input", "inputs"), ("get", "observables")])
def test_ctl_help_lists_every_name_of_every_bundled_profile(command: str, kind: str) -> None:
    """Module names (`sequencer`, `crisp`, `index_missing`...) too, each with the profiles that
    have it; names every profile of a family has are listed once for the family."""
    code, out, _ = run("ctl", command, "--help")
    assert code == 0
    names, families = every_bundled_name(kind)
    for name, profiles in names.items():
        assert re.search(rf"\b{name}\b", out), name
        family = families[next(iter(profiles))]
        if len(profiles) < sum(1 for f in families.values() if f == family):  # some: the row names them
            row = re.search(rf"^\s+{name}\s+(.+(?:\n\s{{20,}}.+)*)", out, re.MULTILINE)
            assert row is not None, name
            assert set(re.split(r",\s+", row.group(1).strip())) == profiles, name


def test_ctl_input_help_names_the_module_inputs() -> None:
    _, out, _ = run("ctl", "input", "--help")
    assert re.search(r"^\s+sequencer\s+ms2000-seq$", out, re.MULTILINE)
    assert re.search(r"^\s+crisp\s+ms2000-crisp, ms2000-pz-crisp$", out, re.MULTILINE)
    assert re.search(r"^\s+index_missing\s+ms2000-all-modules, ms2000-seq$", out, re.MULTILINE)
    assert re.search(r"^\s+scan_drop_pulses\s+ms2000-scan$", out, re.MULTILINE)


def test_describe_shows_the_allowed_range() -> None:
    """The text output carries what `--json` calls `type`: the type and range of each key."""
    _, out, _ = run("describe", "mp285")
    _, listing, _ = run("describe", "mp285", "--json")
    rows = {row["path"]: row for row in json.loads(listing)}
    settle = next(line for line in out.splitlines() if line.startswith("knobs.settle_s "))
    assert f"allowed {rows['knobs.settle_s']['type']} " in settle
    assert "allowed number >= 0" in settle


def test_validate_reports_every_problem_in_file_order(tmp_path: Path) -> None:
    """Not one problem per run in schema order: all of them, by line (issue "Hardening, round two")."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "spec: 2\n"
        "device: mp285\n"
        "knobs:\n"
        "  settle_s: -1\n"
        "  frobnicate: true\n"
        "line:\n"
        "  baud: 14400\n"
        "controller: {model: nope}\n"
    )
    code, out, err = run("validate", str(bad))
    assert (code, out) == (1, "")
    starts = [
        f"{bad}:1: spec: 2 is not a supported version (only 1)",
        f"{bad}:4: knobs.settle_s: -1 is out of range",
        f"{bad}:5: knobs.frobnicate: unknown key; allowed here: ",
        f"{bad}:7: line.baud: 14400 is not one of ",
        f"{bad}:8: controller.model: 'nope' is not one of 'mp285', 'mp285a'",
    ]
    lines = err.splitlines()
    assert len(lines) == len(starts)
    for line, start in zip(lines, starts, strict=True):
        assert line.startswith(start), line


def test_validate_a_rig_reports_its_problems_then_its_profiles(tmp_path: Path) -> None:
    """The rig's own problems and its overrides' by line, then those in a profile file it names;
    a device whose ports are wrong still has its profile and overrides checked."""
    profile = tmp_path / "bad.yaml"
    profile.write_text("spec: 1\ndevice: probe\nline:\n  baud: 14400\n")
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "spec: 1\n"
        "devices:\n"
        "  - name: a\n"
        f"    profile: {PROBE}\n"
        "    overrides: {line: {parity: mark}}\n"
        "    ports: [{channel: main, timing: slow}]\n"
        "  - name: b\n"
        "    profile: bad.yaml\n"
        "    colour: red\n"
    )
    code, _, err = run("validate", str(rig))
    assert code == 1
    assert err.splitlines() == [
        f"{rig}:5: line.parity: 'mark' is not one of 'none', 'even', 'odd'",
        f"{rig}:6: devices[0].ports[0].timing: 'slow' is not one of 'realistic', 'fast'",
        f"{rig}:9: devices[1].colour: unknown key; allowed here: name, overrides, ports, profile",
        f"{display_path(profile)}:4: line.baud: 14400 is not one of 1200, 2400, 4800, 9600, 19200, 115200",
    ]


def test_validate_a_file_with_very_many_problems_is_one_line(tmp_path: Path) -> None:
    """Past MAX_PROBLEMS it is not a profile with a few slips: its first problem and the count."""
    wide = tmp_path / "wide.yaml"
    wide.write_text("spec: 1\ndevice: probe\n" + "".join(f"k{i}: 1\n" for i in range(MAX_PROBLEMS + 1)))
    code, _, err = run("validate", str(wide))
    assert code == 1
    assert err.splitlines() == [
        f"{wide}:3: k0: unknown key; allowed here: knobs, line (and {MAX_PROBLEMS} more problems)"
    ]
    at_limit = tmp_path / "fifty.yaml"
    at_limit.write_text("spec: 1\ndevice: probe\n" + "".join(f"k{i}: 1\n" for i in range(MAX_PROBLEMS)))
    assert len(run("validate", str(at_limit))[2].splitlines()) == MAX_PROBLEMS


def test_serve_lists_every_problem_of_its_rig(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("spec: 3\ndevices: []\n")
    code, _, err = run("serve", str(rig))
    assert code == 1
    assert err.splitlines() == [
        f"stage-emu: {rig}:1: spec: 3 is not one of 1",
        f"stage-emu: {rig}:2: devices: has 0 items, expected at least 1",
    ]
