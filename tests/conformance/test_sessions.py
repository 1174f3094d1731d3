"""Recorded sessions as conformance cases: every tests/conformance/DEVICE/sessions/*.jsonl (from
`stage-emu proxy --record`, saved with `stage-emu replay --save-test`) has its host side replayed on
the target and must get the recorded replies, byte for byte and in time. On a real controller
(`--port ... --device ...`) the sessions of its family whose profile is the family's own run.

emulator/tools/replay.py plays a session on the wall clock, with a thread reading the port: in virtual
time that thread's reads would move device time ahead of the schedule. So in virtual time (the
default target) a session replays on a device of the same profile in this process in real time
(`stageemu://PROFILE`), as `stage-emu replay` does without `--port`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from emulator.tools.replay import ReplayOptions, emulator_url, replay
from emulator.tools.session import load_session
from tests.conformance.conftest import Target

SESSIONS = sorted(Path(__file__).parent.glob("*/sessions/*.jsonl"))
#: how far a reply may move: as `SLACK` in mp285/wire.py, the daemon's and the host's scheduling on a
#: loaded 2-core machine (a few ms typically, tens at worst) and reading through the PTY
TOLERANCE_S = 0.030
#: lateness a loaded machine may add (as `LOAD` in mp285/wire.py): a reply is never early, and exact
#: instants are checked in virtual time by the vectors; on a real controller the tolerance is exact
LOAD_S = 1.0


def session_id(path: Path) -> str:
    """`FAMILY-NAME`: tests/conformance/FAMILY/sessions/NAME.jsonl's test id."""
    return f"{path.parents[1].name}-{path.stem}"


@pytest.mark.smoke
@pytest.mark.parametrize("path", SESSIONS, ids=session_id)
def test_session_replays(path: Path, open_target: Callable[..., Target]) -> None:
    session = load_session(path)
    profile = session.header.profile
    target = open_target(profile)
    port = target.open(path=emulator_url(profile, "realistic")) if target.virtual else target.open()
    late = 0.0 if target.real else LOAD_S
    result = replay(session, port, ReplayOptions(TOLERANCE_S, late_allowance_s=late))
    assert result.ok, "\n".join([*result.report(), result.summary(str(port.port))])
