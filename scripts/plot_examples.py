"""The README's `stage-emu plot` pictures, recorded from a served emulator in a few seconds.

    python scripts/plot_examples.py [--out docs/images] [--only DEVICE ...]

One daemon serves four MS-2000s at `--time-scale 10` with `--log-traffic`; through pyserial, the
control channel and the `stage-emu gcode` command it records (a) a 3×2 ARRAY self-scan on
`ms2000-all-modules`, (b) a serpentine SCAN on `ms2000-scan`, (c) a 1 mm circle traced with the
output on by `stage-emu gcode` on `ms2000-tracer`, (d) a CRISP focus lock following a drifting
sample on `ms2000-crisp`, then stops the daemon and draws each device with `stage-emu plot` into
array-3x2.png, scan-serpentine.png, gcode-circle.png and crisp-lock.png (a focus figure: the device
has CRISP records). The integration tests run the same steps.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from emulator.cli import main as stage_emu
from emulator.control_client import ControlClient
from emulator.hosting.launcher import RunningDaemon, start_daemon
from protocols.clients import MS2000

ROOT = Path(__file__).resolve().parents[1]
ARRAY_DEVICE = "ms2000-all-modules"
SCAN_DEVICE = "ms2000-scan"
TRACER_DEVICE = "ms2000-tracer"
CRISP_DEVICE = "ms2000-crisp"
#: device seconds per wall second: the three sessions take about 10 s of device time
TIME_SCALE = 10.0
#: wall seconds without an awaited event before a session is declared stuck
PATIENCE_S = 10.0
SCAN_LINES = 5
#: a 1 mm circle (0.5 mm radius) about the start, traced clockwise with the output on (M03)
CIRCLE = """\
%
(a 1 mm circle, laser on along it)
G21 G90
G00 X0.5 Y0
M03
G02 X0.5 Y0 I-0.5 J0 F300
M05
G00 X0 Y0
%
"""
FIGURES = {
    ARRAY_DEVICE: ("array-3x2.png", "ARRAY 3×2 self-scan (AR X=3 Y=2 Z=0.5 F=0.4), ms2000-all-modules"),
    SCAN_DEVICE: ("scan-serpentine.png", f"Serpentine SCAN, {SCAN_LINES} lines (SN F=1), ms2000-scan"),
    TRACER_DEVICE: ("gcode-circle.png", "stage-emu gcode: a 1 mm circle, ms2000-tracer"),
    CRISP_DEVICE: ("crisp-lock.png", "CRISP holds focus on a drifting sample (LK F=83), ms2000-crisp"),
}


class Stuck(RuntimeError):
    """A session did not get where it should within PATIENCE_S."""


def serve(workdir: Path, log: Path, profiles: Sequence[str]) -> RunningDaemon:
    args = [arg for profile in profiles for arg in ("--profile", profile)]
    args += ["--log-traffic", str(log), "--time-scale", str(TIME_SCALE)]
    return start_daemon(workdir, args, len(profiles), cwd=ROOT)


def array_self_scan(daemon: RunningDaemon, device: str = ARRAY_DEVICE) -> None:
    """A 3×2 grid, 0.5 mm by 0.4 mm, cell (1,1) where the stage is, visited by a bare `AR`."""
    control = daemon.control()
    control.subscribe(device)
    with MS2000(daemon.port(device)) as stage:
        for command in ("AR X=3 Y=2 Z=0.5 F=0.4", "AH", "RT Z=100", "AR"):
            stage.command(command)
        _count(control.events(timeout=PATIENCE_S), device, "array_arrival", 6)


def serpentine_scan(daemon: RunningDaemon, device: str = SCAN_DEVICE) -> None:
    """X sweeps 0.4 mm per line, Y steps over 0.2 mm, alternating direction, pixels counted."""
    control = daemon.control()
    control.subscribe(device)
    with MS2000(daemon.port(device)) as stage:
        for command in ("SN X=1 Y=2 F=1", "NR X=0 Y=0.4 Z=24", f"NV X=0 Y=0.2 Z={SCAN_LINES} F=1", "TTL X=1"):
            stage.command(command)
        stage.command("SN")
        _count(control.events(timeout=PATIENCE_S), device, "scan_pixels", SCAN_LINES)
        stage.wait_until_idle(timeout=PATIENCE_S)  # the fast axis goes back to its start


def gcode_circle(daemon: RunningDaemon, workdir: Path, device: str = TRACER_DEVICE) -> None:
    """`stage-emu gcode` runs CIRCLE. Backlash is switched off first: with the profile's `B` every
    chord heading down or left would end in a 40 µm backlash leg out and back (MS-57)."""
    with MS2000(daemon.port(device), 115200) as stage:
        stage.command("B X=0 Y=0")
    program = workdir / "circle.nc"
    program.write_text(CIRCLE)
    run_cli(["gcode", str(program), "--port", daemon.port(device)])


def crisp_lock(daemon: RunningDaemon, device: str = CRISP_DEVICE) -> None:
    """CRISP locks (bare `LK`: ready, `LK F=83`: lock) and keeps Z on the sample as it drifts up at
    2 µm/s, jumps 3 µm and drifts down at 1 µm/s (control input `crisp`); a commanded 5 µm Z move
    (`R Z=50`) holds the lock off meanwhile (`N`), after which it pulls Z back; bare `UL` unlocks."""
    control = daemon.control()
    with MS2000(daemon.port(device)) as stage:
        stage.command("LK")
        stage.command("LK F=83")
        deadline = time.monotonic() + PATIENCE_S
        while stage.exchange("LK X?") != ":A F":
            if time.monotonic() > deadline:
                raise Stuck(f"{device}: no focus lock within {PATIENCE_S} s")
        device_wait(control, 0.5)
        control.input(device, "crisp", drift_um_per_s=2.0)
        device_wait(control, 2.0)
        surface_um = control.get(device, "crisp")["surface_um"]
        control.input(device, "crisp", surface_um=surface_um + 3.0, drift_um_per_s=0.0)
        device_wait(control, 1.0)
        stage.command("R Z=50")
        device_wait(control, 1.5)
        control.input(device, "crisp", drift_um_per_s=-1.0)
        device_wait(control, 2.0)
        control.input(device, "crisp", drift_um_per_s=0.0)
        device_wait(control, 0.5)
        stage.command("UL")


def device_wait(control: ControlClient, seconds: float) -> None:
    """Let `seconds` of device time pass (the daemon's clock runs TIME_SCALE times wall time)."""
    until = float(control.clock()["now"]) + seconds
    deadline = time.monotonic() + PATIENCE_S
    while float(control.clock()["now"]) < until:
        if time.monotonic() > deadline:
            raise Stuck(f"device time stood still for {PATIENCE_S} s")
        time.sleep(0.01)


def _count(events: Iterator[dict[str, Any]], device: str, name: str, count: int) -> None:
    """Wait for `count` events called `name` among a subscription's `events`."""
    seen = 0
    for event in events:
        seen += event.get("ev") == name
        if seen == count:
            return
    raise Stuck(f"{device}: {seen} of {count} {name} events within {PATIENCE_S} s")


def run_cli(args: list[str]) -> None:
    """`stage-emu ARGS` in this process; a failure (exit status 1, its line on stderr) raises."""
    try:
        stage_emu.main(args, prog_name="stage-emu", standalone_mode=False)
    except SystemExit as exc:
        if exc.code:
            raise RuntimeError(f"stage-emu {args[0]} failed (exit {exc.code})") from None


def record(workdir: Path, devices: Sequence[str]) -> Path:
    """The sessions of `devices` (FIGURES keys) in one traffic log, which it returns once the daemon
    has stopped."""
    sessions: dict[str, Callable[[RunningDaemon], None]] = {
        ARRAY_DEVICE: array_self_scan,
        SCAN_DEVICE: serpentine_scan,
        TRACER_DEVICE: lambda daemon: gcode_circle(daemon, workdir),
        CRISP_DEVICE: crisp_lock,
    }
    log = workdir / "traffic.jsonl"
    daemon = serve(workdir, log, devices)
    try:
        for device in devices:
            sessions[device](daemon)
    finally:
        daemon.stop()
    return log


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images", help="where the PNGs go")
    parser.add_argument(
        "--only", action="append", choices=list(FIGURES), help="record and draw only this device (repeatable)"
    )
    options = parser.parse_args(argv)
    options.out.mkdir(parents=True, exist_ok=True)
    devices = options.only or list(FIGURES)
    with tempfile.TemporaryDirectory(prefix="plot-examples-") as tmp:
        log = record(Path(tmp), devices)
        for device in devices:
            name, title = FIGURES[device]
            output = options.out / name
            run_cli(["plot", str(log), "-o", str(output), "--device", device, "--title", title])
            print(f"{output}: {output.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
