"""The MS2000 package has no hub: no import circle, counting imports made only for type checking,
reaches the model, and what circles remain are one class split over files for size (an axis and
its position servo; CRISP and its commands and routines). Read with scripts/import_cycles.py."""

from __future__ import annotations

from pathlib import Path

from scripts.import_cycles import cycles, import_graph

PACKAGE = Path(__file__).resolve().parents[3] / "emulator" / "devices" / "ms2000"
P = "emulator.devices.ms2000."
SPLIT_CLASSES = [
    {P + "axis", P + "drift"},
    {P + "modules.crisp", P + "modules.crisp_commands", P + "modules.crisp_routines"},
]


def test_only_split_classes_form_circles_even_at_type_level() -> None:
    found = cycles(import_graph(PACKAGE, typing=True, parents=False))
    assert sorted(map(set, found), key=len) == sorted(SPLIT_CLASSES, key=len)


def test_no_circle_at_run_time_but_through_the_package_init() -> None:
    """At run time only the edge every import has to the package's `__init__` (which registers the
    family, model included) closes circles; the files' own imports close none."""
    assert cycles(import_graph(PACKAGE, typing=False, parents=False)) == []


def test_a_circle_is_found(tmp_path: Path) -> None:
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from pkg import b\n")
    (package / "b.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.a import X\n"
    )
    (package / "c.py").write_text("import pkg.a\n")
    assert cycles(import_graph(package, typing=True, parents=False)) == [["pkg.a", "pkg.b"]]
    assert cycles(import_graph(package, typing=False, parents=False)) == []
