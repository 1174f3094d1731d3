"""Recorded sessions as conformance cases: every tests/conformance/DEVICE/sessions/*.jsonl (from
`stage-emu proxy --record`, saved with `stage-emu replay --save-test`) has its host side replayed on
the target and must get the recorded replies, byte for byte and in time. On a real controller
(`--port ... --device ...`) the sessions of its family whose profile is the family's own run.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from emulator.replay import ReplayOptions, replay
from emulator.session import load_session
from tests.conformance.conftest import Target

SESSIONS = sorted(Path(__file__).parent.glob("*/sessions/*.jsonl"))
#: how far a reply may move: as `SLACK` in mp285/wire.py, the daemon's and the host's scheduling on a
#: loaded 2-core machine (a few ms typically, tens at worst) and reading through the PTY
TOLERANCE_S = 0.030


@pytest.mark.parametrize("path", SESSIONS, ids=lambda path: f"{path.parents[1].name}-{path.stem}")
def test_session_replays(path: Path, open_target: Callable[..., Target]) -> None:
    session = load_session(path)
    target = open_target(session.header.profile)
    result = replay(session, target.open(), ReplayOptions(TOLERANCE_S))
    assert result.ok, "\n".join([*result.report(), result.summary(target.path)])
