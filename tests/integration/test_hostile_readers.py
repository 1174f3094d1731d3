"""The offline readers as a user meets them (issue "Hardening, round two", item 5): a short form of
the torture suite's hostile-reader corpus (scripts/soak/hostile_readers.py), and the progress line
that `plot`, `replay` and `gcode` draw on stderr only when it is a terminal.

Wall time is a figure here, not a bound (a shared 2-core machine makes it flaky), except where it
is the point: a hostile input that used to hang must be refused within seconds."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
from pathlib import Path

from scripts.soak.hostile_readers import ROOT, hostile_readers, write_big_gcode, write_big_log

#: a hang used to last for ever; a loaded machine still answers within this
HANG_S = 10.0


def test_hostile_files_are_refused_in_one_line_and_big_ones_read_in_bounded_memory(tmp_path: Path) -> None:
    out = hostile_readers(tmp_path, log_mb=3, gcode_moves=50_000)
    timing = [e for e in out.exceeded if ": took " in e]
    assert [e for e in out.exceeded if e not in timing] == [], out.figures
    assert out.figures["slowest_s"] < HANG_S, out.figures
    assert out.figures["cases"] == 27


def _stderr_of(args: list[str], *, terminal: bool) -> bytes:
    """`stage-emu ARGS` with stdout to /dev/null and stderr a pseudo-terminal (or a pipe)."""
    command = [sys.executable, "-m", "emulator.cli", *args]
    if not terminal:
        done = subprocess.run(command, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, timeout=120, check=False)  # fmt: skip
        return done.stderr
    master, slave = os.openpty()
    proc = subprocess.Popen(
        command, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave
    )
    os.close(slave)
    seen = b""
    try:
        while select.select([master], [], [], 120)[0]:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not chunk:
                break
            seen += chunk
    finally:
        os.close(master)
        proc.wait(timeout=120)
    return seen


def _session(path: Path, writes: int) -> Path:
    header = {"session": "stage-emu", "version": 1, "device": "ms2000", "profile": "ms2000"}
    header["line"] = {"baud": 9600, "data_bits": 8, "parity": "none", "stop_bits": 1}
    lines = [json.dumps(header)]
    lines += [json.dumps({"t": i * 1e-4, "dir": "rx", "hex": "0d"}) for i in range(writes)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_progress_shows_on_a_terminal_and_not_in_a_pipe(tmp_path: Path) -> None:
    log = tmp_path / "t.jsonl"
    write_big_log(log, 0.5)
    program = tmp_path / "p.nc"
    write_big_gcode(program, 3000)
    session = _session(tmp_path / "s.jsonl", 1500)
    runs = {
        "stage-emu plot: reading": ["plot", str(log), "-o", str(tmp_path / "p.png")],
        "stage-emu gcode: planning": ["gcode", str(program), "--dry-run"],
        "stage-emu replay: checking": ["replay", str(session), "--timing", "fast"],
    }
    for label, args in runs.items():
        shown = _stderr_of(args, terminal=True).decode()
        assert f"\r{label} " in shown and " 1,024 " in shown, (label, shown)
        assert "\r\x1b[K" in shown, "the line is wiped when the work is done"
        piped = _stderr_of(args, terminal=False).decode()
        assert label not in piped and "\r" not in piped, (label, piped)
