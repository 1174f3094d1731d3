"""Rig specs built from `--profile` options and from the bundled default rig."""

from __future__ import annotations

from pathlib import Path

import tests.support.probe_device  # noqa: F401  (registers the `probe` family)
from emulator.profile import bundled_dir
from emulator.rig import load_rig, rig_from_profiles

PROBE = str(Path(__file__).parent.parent / "support" / "probe.yaml")


def test_profile_options_name_devices_after_their_profile(tmp_path: Path) -> None:
    link = tmp_path / "ttyProbe"
    rig = rig_from_profiles([PROBE, f"{PROBE}:{link}", "mp285"])
    assert [d.name for d in rig.devices] == ["probe", "probe-2", "mp285"]
    assert [d.ports[0].link for d in rig.devices] == [None, link, None]


def test_bundled_rig_serves_one_controller_of_each_family() -> None:
    rig = load_rig(bundled_dir() / "rig.yaml")
    assert [(d.name, d.profile.family) for d in rig.devices] == [("mp285", "mp285"), ("ms2000", "ms2000")]
