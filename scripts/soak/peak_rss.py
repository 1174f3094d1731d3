"""Run `stage-emu ARGS` (as `python -m emulator.cli ARGS` would) and, at its exit, write its own
peak resident memory in kB (VmHWM) to the file named by `STAGE_EMU_PEAK_FILE`.

Why not the `ru_maxrss` that os.wait4 gives of the child: Linux carries the spawning process's
high-water mark over `exec` into the child's, so a command started from a large process (a pytest
run that has drawn figures, at 140 MB) reads as at least that large. VmHWM belongs to the memory
of the program after `exec` alone.
"""

from __future__ import annotations

import atexit
import os
import runpy
import sys
from pathlib import Path

ENV = "STAGE_EMU_PEAK_FILE"


def _write_peak() -> None:
    with open("/proc/self/status") as status:
        peak = next((line.split()[1] for line in status if line.startswith("VmHWM:")), "")
    Path(os.environ[ENV]).write_text(peak)


if __name__ == "__main__":
    atexit.register(_write_peak)
    sys.argv = ["stage-emu", *sys.argv[1:]]
    runpy.run_module("emulator.cli", run_name="__main__", alter_sys=True)
