"""A G-code interpreter for any MS-2000 (MS-TRACER-5): the subset of ASI's Tracer Console, run with
high-level commands through the MS2000 client, so it needs no Tracer firmware.

    from protocols.clients import MS2000
    from protocols.clients.gcode import GcodeExecutor, parse_program

    steps = parse_program("G21 G90\\nG01 X1 F60\\n")   # a plan: testable without a port
    with MS2000("/dev/ttyUSB0", baudrate=115200) as stage:
        executor = GcodeExecutor(stage)
        steps = parse_program(text, start=executor.start_position(), xyz_scale=0.01)
        executor.run(steps)

`parse_program` raises `GcodeError` (with the line number) for a program it cannot run;
`GcodeExecutor.run` raises `ExecutionError` when the controller refuses or falls silent. For a
program of any length, `iter_program(lines)` plans a step at a time as the lines come, and
`executor.run(iter_program(...), axes=moving_axes(iter_program(...)))` sends it in one pass.
"""

from protocols.clients.gcode.executor import ExecutionError, GcodeExecutor, RunSummary, run_program
from protocols.clients.gcode.parser import GcodeError, iter_blocks, iter_program, parse_program, read_program
from protocols.clients.gcode.plan import (
    SAGITTA_MM,
    Dwell,
    Move,
    Output,
    Step,
    arc_chords,
    chord_count,
    iter_arc_chords,
    moving_axes,
)

__all__ = [
    "SAGITTA_MM",
    "Dwell",
    "ExecutionError",
    "GcodeError",
    "GcodeExecutor",
    "Move",
    "Output",
    "RunSummary",
    "Step",
    "arc_chords",
    "chord_count",
    "iter_arc_chords",
    "iter_blocks",
    "iter_program",
    "moving_axes",
    "parse_program",
    "read_program",
    "run_program",
]
