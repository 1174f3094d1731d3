"""`stage-emu plot`: PNG and SVG figures from a traffic log, and one line with exit status 1 (never a
traceback) for whatever it cannot do, a missing matplotlib included."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner, Result

from emulator.cli import main
from emulator.cli.plot import NEEDS_MATPLOTLIB

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def run(*args: str) -> Result:
    return CliRunner().invoke(main, ["plot", *args])


def session_log(path: Path) -> Path:
    """An ARRAY-and-laser session whose Z also moves: every mark and the Z-over-time panel."""
    records: list[dict[str, Any]] = [
        {"t": 0.0, "device": "stage", "dir": "ev", "ev": "ttl_out0", "level": 1},
        {"t": 0.0, "device": "stage", "dir": "ev", "ev": "move", "path": {"X": [[0.0, 0.0], [1.0, 1500.0]]}},
        {"t": 0.0, "device": "stage", "dir": "ev", "ev": "move", "path": {"Z": [[0.0, 0.0], [2.0, -20.0]]}},
        {"t": 1.0, "device": "stage", "dir": "ev", "ev": "array_arrival", "i": 1, "j": 1},
        {"t": 1.0, "device": "stage", "dir": "ev", "ev": "ttl_out0", "level": 0},
        {"t": 1.0, "device": "stage", "dir": "ev", "ev": "move", "path": {"Y": [[1.0, 0.0], [2.0, 800.0]]}},
        {"t": 1.5, "device": "stage", "dir": "ev", "ev": "scan_sync", "line": 1},
        {"t": 2.0, "device": "stage", "dir": "ev", "ev": "scan_pixels", "line": 1, "count": 7},
        {"t": 2.0, "device": "stage", "dir": "ev", "ev": "array_arrival", "i": 1, "j": 2},
    ]
    path.write_text("".join(json.dumps({"wall": 0.0, **r}) + "\n" for r in records))
    return path


@pytest.mark.parametrize("view", ["xy", "xyz"])
def test_png_and_svg_figures(tmp_path: Path, view: str) -> None:
    log = session_log(tmp_path / "traffic.jsonl")
    png, svg = tmp_path / "path.png", tmp_path / "path.SVG"
    for output in (png, svg):
        result = run(str(log), "-o", str(output), "--axes", view)
        assert result.exit_code == 0, result.output
        assert result.stdout == f"{output}: stage, 2.00 s of device time\n"
    assert png.read_bytes().startswith(PNG_SIGNATURE)
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text
    # matplotlib draws text as glyph paths, each preceded by a comment with the text
    for label in ("X (mm)", "laser on (OUT0 high)", "laser off (OUT0 low)", "ARRAY cell (arrival order)"):
        assert f"<!-- {label} -->" in text
    assert ("<!-- Z over time -->" in text) is (view == "xy"), "the 3-D view shows Z itself"


def test_missing_matplotlib_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` now raises ImportError
    result = run(str(session_log(tmp_path / "t.jsonl")), "-o", str(tmp_path / "p.png"))
    assert (result.exit_code, result.stderr) == (1, NEEDS_MATPLOTLIB + "\n")
    assert not (tmp_path / "p.png").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["{tmp}/missing.jsonl", "-o", "{tmp}/p.png"], "{tmp}/missing.jsonl: no such file"),
        (["{tmp}/garbage.jsonl", "-o", "{tmp}/p.png"], "{tmp}/garbage.jsonl:1: not a traffic log"),
        (["{tmp}/quiet.jsonl", "-o", "{tmp}/p.png"], "{tmp}/quiet.jsonl: no move records"),
        (["{tmp}/t.jsonl", "-o", "{tmp}/p.png", "--device", "ghost"], "{tmp}/t.jsonl: no device 'ghost'"),
        (["{tmp}/t.jsonl", "-o", "{tmp}/p.pdf"], "{tmp}/p.pdf: the output must end in .png or .svg"),
        (["{tmp}/t.jsonl", "-o", "{tmp}/no/such/dir/p.png"], "{tmp}/no/such/dir/p.png: cannot write it"),
        (["{tmp}/t.jsonl", "-o", "{tmp}/t.jsonl/p.svg"], "{tmp}/t.jsonl/p.svg: cannot write it: Not a dir"),
    ],
)
def test_what_it_cannot_do_is_one_line_and_exit_1(tmp_path: Path, args: list[str], message: str) -> None:
    session_log(tmp_path / "t.jsonl")
    (tmp_path / "garbage.jsonl").write_text("not json\n")
    (tmp_path / "quiet.jsonl").write_text(
        json.dumps({"t": 0.0, "wall": 0.0, "device": "stage", "dir": "rx", "port": "main", "hex": "56 0d"})
        + "\n"
    )
    result = run(*(arg.format(tmp=tmp_path) for arg in args))
    assert result.exit_code == 1
    assert result.stderr.startswith("stage-emu: " + message.format(tmp=tmp_path))
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
