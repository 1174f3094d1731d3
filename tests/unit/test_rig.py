"""Rig specs built from `--profile` options and from the bundled default rig."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from emulator.hosting.rig import load_rig, rig_from_profiles
from emulator.profiles.profile import ProfileError, bundled_dir
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)


def test_profile_options_name_devices_after_their_profile(tmp_path: Path) -> None:
    link = tmp_path / "ttyProbe"
    rig = rig_from_profiles([PROBE, f"{PROBE}:{link}", "mp285"])
    assert [d.name for d in rig.devices] == ["probe", "probe-2", "mp285"]
    assert [d.ports[0].link for d in rig.devices] == [None, link, None]


def test_bundled_rig_serves_one_controller_of_each_family() -> None:
    rig = load_rig(bundled_dir() / "rig.yaml")
    assert [(d.name, d.profile.family) for d in rig.devices] == [("mp285", "mp285"), ("ms2000", "ms2000")]


def rig_error(path: Path) -> str:
    with pytest.raises(ProfileError) as info:
        load_rig(path)
    return str(info.value)


def test_rig_files_go_through_the_profile_reader(tmp_path: Path) -> None:
    """Rig files get the same limits and one-line messages as profiles (issue #9)."""
    os.mkfifo(tmp_path / "fifo.yaml")
    assert (
        rig_error(tmp_path / "fifo.yaml")
        == f"{tmp_path / 'fifo.yaml'}: is a FIFO (named pipe), not a regular file"
    )
    assert rig_error(tmp_path) == f"{tmp_path}: is a directory, not a file"
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &a [" + ", ".join(["x"] * 400) + "]\nb: [" + ", ".join(["*a"] * 400) + "]\n")
    assert "bomb.yaml:1: more than 100000 YAML nodes (aliases expanded)" in rig_error(bomb)


def test_rig_description_is_one_line(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(f'spec: 1\ndescription: "a\\nb"\ndevices: [{{name: a, profile: {PROBE}}}]\n')
    assert rig_error(rig) == f"{rig}:2: description: 'a\\nb' is not one line of printable text"


def test_every_cross_device_problem_is_found_at_its_device(tmp_path: Path) -> None:
    """Each repeat is reported (not only the first), at the entry of the later device."""
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "spec: 1\n"
        "devices:\n"
        f"  - {{name: a, profile: {PROBE}, ports: [{{link: x}}]}}\n"
        f"  - {{name: a, profile: {PROBE}}}\n"
        f"  - {{name: b, profile: {PROBE}, ports: [{{link: x}}, {{channel: aux}}]}}\n"
    )
    with pytest.raises(ProfileError) as info:
        load_rig(rig)
    assert [p.text for p in info.value.problems] == [
        f"{rig}:4: devices[1]: device name 'a' is used twice",
        f"{rig}:5: devices[2]: device 'b' has no channel 'aux' (it has: main)",
        f"{rig}:5: devices[2]: link {tmp_path / 'x'} is used by two ports",
    ]
