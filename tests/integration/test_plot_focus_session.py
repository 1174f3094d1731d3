"""`stage-emu plot`'s focus figure of real sessions: a daemon served with `--log-traffic` at a time
scale, CRISP locked on a drifting sample (scripts/plot_examples.py `crisp_lock`, the README picture)
and an `AF` run on `ms2000-af`, then read back and drawn to PNG."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.tools.plot_scan import read_focus
from protocols.clients import MS2000
from scripts.plot_examples import CRISP_DEVICE, PATIENCE_S, crisp_lock, serve

AF_DEVICE = "ms2000-af"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: where the simulated focus curve peaks (user µm of Z), inside the run's ±50 µm
AF_PEAK_UM = 12.0


@pytest.fixture(scope="module")
def traffic_log(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    workdir = tmp_path_factory.mktemp("plot-focus")
    log = workdir / "traffic.jsonl"
    daemon = serve(workdir, log, [CRISP_DEVICE, AF_DEVICE])
    try:
        crisp_lock(daemon)
        daemon.control().input(AF_DEVICE, "focus", peak_um=AF_PEAK_UM)
        with MS2000(daemon.port(AF_DEVICE), timeout=PATIENCE_S) as stage:
            stage.command("AF")  # answers when the run has ended (MS-33)
    finally:
        assert daemon.stop() == 0, daemon.stderr()
    yield log


def test_the_crisp_lock_is_read_back(traffic_log: Path) -> None:
    focus = read_focus(traffic_log, CRISP_DEVICE)
    assert focus.axis == "Z" and not focus.autofocus
    states = [change.state for change in focus.states]
    assert states[:3] == ["R", "K", "F"], "bare LK, then LK F=83 locks and settles in focus"
    assert "N" in states, "R Z=50 holds the lock off"
    assert states[-1] == "R", "bare UL unlocks"
    assert len(focus.readings) > 100, "a crisp_sample per lock-loop update (UL Y = 10 ms)"
    band = focus.states[-1].in_focus_counts
    in_focus = [r for r in focus.readings if (s := focus.state_at(r.t)) is not None and s.state == "F"]
    assert in_focus and all(abs(r.error) <= band for r in in_focus)
    last = focus.readings[-1]
    assert last.surface_um > 3.0, "the sample drifted and jumped up"
    assert focus.z_um(last.t) == pytest.approx(last.surface_um, abs=0.1), "Z followed it"


def test_the_af_run_is_read_back(traffic_log: Path) -> None:
    focus = read_focus(traffic_log, AF_DEVICE)
    assert not focus.crisp and len(focus.runs) == 1
    run = focus.runs[0]
    assert (run.result, run.calibrating) == ("focused", False)
    assert run.end is not None and run.peak_um == pytest.approx(AF_PEAK_UM, abs=1.0)
    assert focus.z_um(focus.session.end) == pytest.approx(run.peak_um, abs=0.05), "Z went to the peak"
    scanned = [s for s in focus.samples if run.start <= s.t <= run.end]
    assert len(scanned) > 30, "an af_sample per video frame of the scan"
    best = max(scanned, key=lambda s: s.value)
    assert best.z_um == pytest.approx(AF_PEAK_UM, abs=2.0)


@pytest.mark.parametrize(
    ("device", "panel"), [(CRISP_DEVICE, "CRISP focus error"), (AF_DEVICE, "AUTOFOCUS runs")]
)
def test_plot_draws_the_focus_figure(traffic_log: Path, tmp_path: Path, device: str, panel: str) -> None:
    png, svg = tmp_path / "focus.png", tmp_path / "focus.svg"
    for output in (png, svg):
        result = CliRunner().invoke(main, ["plot", str(traffic_log), "-o", str(output), "--device", device])
        assert result.exit_code == 0, result.output
        assert result.stdout.startswith(f"{output}: {device}, ")
    assert png.read_bytes().startswith(PNG_SIGNATURE) and png.stat().st_size > 20_000
    assert panel in svg.read_text(), "the focus figure, chosen because the device has focus records"
