"""`stage-emu plot` of real sessions: a daemon served with `--log-traffic` (at a time scale), driven
through pyserial and `stage-emu gcode` as scripts/plot_examples.py does for the README pictures,
then drawn. The brief's "done means": `stage-emu gcode` traces a 1 mm circle on `ms2000-tracer` and
`stage-emu plot` renders it."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.tools.plot import Session
from emulator.tools.plot_scan import read_session
from scripts.plot_examples import ARRAY_DEVICE, TRACER_DEVICE, array_self_scan, gcode_circle, serve

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def traffic_log(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """One log of two devices: a 3×2 ARRAY self-scan and a G-code circle."""
    workdir = tmp_path_factory.mktemp("plot")
    log = workdir / "traffic.jsonl"
    daemon = serve(workdir, log, [ARRAY_DEVICE, TRACER_DEVICE])
    try:
        array_self_scan(daemon)
        gcode_circle(daemon, workdir)
    finally:
        assert daemon.stop() == 0, daemon.stderr()
    yield log


def position(session: Session, t: float) -> tuple[float, float]:
    return session.at("X", t), session.at("Y", t)


def test_array_cells_are_where_the_grid_puts_them(traffic_log: Path) -> None:
    """`AR X=3 Y=2 Z=0.5 F=0.4` from (0, 0), serpentine: arrivals numbered 1-6 at the cells."""
    session = read_session(traffic_log, ARRAY_DEVICE)
    assert [(a.number, a.i, a.j) for a in session.arrivals] == [
        (1, 1, 1),
        (2, 2, 1),
        (3, 3, 1),
        (4, 3, 2),
        (5, 2, 2),
        (6, 1, 2),
    ]
    for arrival in session.arrivals:
        x, y = position(session, arrival.t)
        assert x == pytest.approx((arrival.i - 1) * 500, abs=0.01)
        assert y == pytest.approx((arrival.j - 1) * 400, abs=0.01)


def test_the_gcode_circle_is_a_1_mm_circle_traced_with_the_laser_on(traffic_log: Path) -> None:
    session = read_session(traffic_log, TRACER_DEVICE)
    assert [level for _, level in session.laser] == [1, 0], "M03 then M05"
    (on, _), (off, _) = session.laser
    traced = [t for t in session.sample_times() if on <= t <= off]
    points = [position(session, t) for t in traced]
    assert len(points) > 70  # one knot or more per chord
    radii = [math.hypot(x, y) for x, y in points]
    assert min(radii) == pytest.approx(500.0, abs=1.0) and max(radii) == pytest.approx(500.0, abs=0.5)
    sectors = {math.degrees(math.atan2(y, x)) % 360 // 30 for x, y in points}
    assert len(sectors) == 12, "all the way round"


@pytest.mark.parametrize(("device", "suffix"), [(ARRAY_DEVICE, ".png"), (TRACER_DEVICE, ".svg")])
def test_plot_renders_the_session(traffic_log: Path, tmp_path: Path, device: str, suffix: str) -> None:
    output = tmp_path / f"path{suffix}"
    args = ["plot", str(traffic_log), "-o", str(output), "--device", device]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"{output}: {device}, ")
    if suffix == ".png":
        assert output.read_bytes().startswith(PNG_SIGNATURE)
    else:
        assert "<!-- laser on (OUT0 high) -->" in output.read_text()


def test_several_devices_need_device(traffic_log: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["plot", str(traffic_log), "-o", str(tmp_path / "p.png")])
    assert result.exit_code == 1
    assert result.stderr == (
        f"stage-emu: {traffic_log}: moves of several devices ({ARRAY_DEVICE}, {TRACER_DEVICE}): "
        "choose one with --device\n"
    )
