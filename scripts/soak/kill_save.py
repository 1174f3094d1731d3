"""SIGKILL an MS2000 daemon at a random moment of an `SS Z` save, restart it, and check what the
kill left in the state directory (MS-111: saved settings survive a kill -9; emulator/storage/nvstore.py).

`kill_during_save` is used with a few cycles by tests/integration/test_kill_during_save.py and with
many by the torture suite (scripts/torture.py). Every daemon gets its own link directory and control
socket (a fresh working folder whose `state` is a symlink to the shared state directory), so a
restart never depends on what the killed daemon left in its runtime folders; only the state
directory is shared.
"""

from __future__ import annotations

import itertools
import json
import random
import shutil
import signal
import tempfile
import time
from pathlib import Path
from typing import Any

import serial

from emulator.hosting.launcher import RunningDaemon, start_daemon

ARGS = ["--profile", "ms2000", "--timing", "fast"]
DEVICE = "ms2000"
#: the two speeds alternately set and saved; each differs from the factory value (5.1456)
SPEEDS = (2.5, 3.5)
#: `SS Z` round trips timed before the first kill to size the window the kill falls into
CALIBRATION_SAVES = 5
ACK = b":A\r\n"


def kill_during_save(
    cycles: int, state_dir: Path, *, workdir: Path | None = None, seed: int | None = None
) -> dict[str, Any]:
    """Run `cycles` of: set X's speed to the other value, send `SS Z`, SIGKILL the daemon after a
    random delay within one save round trip, check the state file on disk is the old or the new
    one, restart on the same `state_dir` and check that the restart is not refused, no corrupt
    file was set aside, no temporary file is left and the daemon reads back the old or new speed.

    Raises AssertionError at the first broken rule (the state directory is left as it was).
    Returns figures: the seed, the kill window, how many kills kept the new or the old value,
    orphaned temporary files found after kills (kills that landed inside the write), the slowest
    restart."""
    state_dir = Path(state_dir).absolute()
    state_dir.mkdir(parents=True, exist_ok=True)
    seed = random.randrange(1 << 32) if seed is None else seed
    rng = random.Random(seed)
    base = Path(tempfile.mkdtemp(prefix="kill-save-")) if workdir is None else Path(workdir)
    figures: dict[str, Any] = {"seed": seed, "cycles": cycles, "kept_new": 0, "kept_old": 0}
    figures.update(orphaned_temps=0, kills_inside_write=0, max_restart_s=0.0)
    runs = itertools.count(1)

    daemon, _ = _start(base / f"run-{next(runs)}", state_dir, "first start")
    with _port(daemon) as port:
        window, stored = _calibrate(port)
    figures["window_ms"] = round(window * 1000, 3)
    for cycle in range(1, cycles + 1):
        new = SPEEDS[0] if stored != SPEEDS[0] else SPEEDS[1]
        with _port(daemon) as port:
            assert _ask(port, f"S X={new}") == ACK
            port.write(b"SS Z\r")
            # the kill must land at a random instant of the save, so here a fixed wait is the point
            time.sleep(rng.uniform(0.0, window))
            daemon.proc.kill()
        _finish(daemon)
        context = f"cycle {cycle} (seed {seed}, {state_dir})"
        on_disk = _stored_speed(state_dir, context)
        assert on_disk in (stored, new), f"{context}: state file holds {on_disk}, not {stored} or {new}"
        orphans = _temps(state_dir)
        figures["orphaned_temps"] += len(orphans)
        figures["kills_inside_write"] += bool(orphans)

        daemon, took = _start(base / f"run-{next(runs)}", state_dir, context)
        figures["max_restart_s"] = max(figures["max_restart_s"], round(took, 3))
        corrupt = sorted(p.name for p in state_dir.glob("*.corrupt-*"))
        assert not corrupt, f"{context}: corrupt state file set aside: {corrupt}"
        leftover = [p.name for p in _temps(state_dir)]
        assert not leftover, f"{context}: temporary files left after the restart: {leftover}"
        with _port(daemon) as port:
            speed = _speed(port)
        assert speed == on_disk, f"{context}: daemon reads {speed}, the file holds {on_disk}"
        figures["kept_new" if speed == new else "kept_old"] += 1
        stored = speed
    assert daemon.stop() == 0
    _finish(daemon)
    if workdir is None:
        shutil.rmtree(base)
    return figures


def _start(workdir: Path, state_dir: Path, context: str) -> tuple[RunningDaemon, float]:
    workdir.mkdir(parents=True)
    (workdir / "state").symlink_to(state_dir, target_is_directory=True)
    began = time.monotonic()
    try:
        daemon = start_daemon(workdir, ARGS, expect_ports=1)
    except (RuntimeError, TimeoutError) as exc:
        raise AssertionError(f"{context}: the daemon refused to start: {exc}") from exc
    return daemon, time.monotonic() - began


def _finish(daemon: RunningDaemon) -> None:
    """Reap the daemon (SIGKILL if still running), close its pipes and remove its working folder
    (its links and socket; the `state` symlink goes, not what it points to)."""
    daemon.stop(signal.SIGKILL)
    for pipe in (daemon.proc.stdout, daemon.proc.stderr):
        if pipe is not None:
            pipe.close()
    shutil.rmtree(daemon.workdir)


def _port(daemon: RunningDaemon) -> serial.Serial:
    return serial.Serial(daemon.port(DEVICE), 9600, timeout=5)


def _ask(port: serial.Serial, line: str) -> bytes:
    port.write(line.encode() + b"\r")
    return port.read_until(b"\r\n")


def _speed(port: serial.Serial) -> float:
    reply = _ask(port, "S X?")
    assert reply.startswith(b":A X="), f"unexpected reply to S X?: {reply!r}"
    return float(reply[5:].strip())


def _calibrate(port: serial.Serial) -> tuple[float, float]:
    """The slowest of a few `SS Z` round trips (write to `:A`), and the speed saved last."""
    slowest = 0.0
    for i in range(CALIBRATION_SAVES):
        speed = SPEEDS[i % 2]
        assert _ask(port, f"S X={speed}") == ACK
        began = time.monotonic()
        assert _ask(port, "SS Z") == ACK
        slowest = max(slowest, time.monotonic() - began)
    return slowest, speed


def _stored_speed(state_dir: Path, context: str) -> float:
    """X's speed in the state file, read straight from the disk."""
    try:
        (path,) = state_dir.glob("*.json")
        return json.loads(path.read_text())["saved"]["axes"]["X"]["speed"]
    except (ValueError, KeyError, TypeError) as exc:
        raise AssertionError(f"{context}: the state file is missing or unusable: {exc!r}") from exc


def _temps(state_dir: Path) -> list[Path]:
    return [p for p in state_dir.iterdir() if p.name.startswith(".") and p.name.endswith(".tmp")]
