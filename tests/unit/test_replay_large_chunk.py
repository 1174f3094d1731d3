"""`stage-emu replay --timing fast` of a session whose host wrote more than the emulated transmit
buffer in one go: the replay's write used to block forever on the in-process port."""

from __future__ import annotations

import threading
from pathlib import Path

from click.testing import CliRunner, Result

from emulator.cli import main
from emulator.device import LineSettings
from emulator.hosting.port import INPUT_BACKLOG
from emulator.tools.session import RX, TX, Chunk, Header, SessionWriter

LINE = LineSettings(baud=9600, data_bits=8, parity="none", stop_bits=1, rtscts=False, xonxoff=False)
#: generous: the replay itself takes about half a second (its grace period)
JOIN_S = 10.0


def test_replay_of_a_chunk_larger_than_the_transmit_buffer_completes(tmp_path: Path) -> None:
    """An MS2000 line past `max_line` (MS-9: `:N-6`), then a status poll (TV-7)."""
    overlong = b"A" * (INPUT_BACKLOG + 2000) + b"\r"
    path = tmp_path / "large.jsonl"
    writer = SessionWriter(path, Header("ms2000", "ms2000", LINE))
    for event in (
        Chunk(0.0, RX, overlong),
        Chunk(0.01, TX, b":N-6\r\n"),
        Chunk(0.02, RX, b"/\r"),
        Chunk(0.03, TX, b"N\r\n"),
    ):
        writer.event(event)
    writer.close()
    results: list[Result] = []
    replay = threading.Thread(
        target=lambda: results.append(CliRunner().invoke(main, ["replay", str(path), "--timing", "fast"])),
        daemon=True,
    )
    replay.start()
    replay.join(JOIN_S)
    assert not replay.is_alive(), f"the replay still runs after {JOIN_S} s"
    assert (results[0].exit_code, results[0].stdout) == (
        0,
        "2 exchanges replayed on stageemu://ms2000?timing=fast: no difference (timing not compared)\n",
    )
