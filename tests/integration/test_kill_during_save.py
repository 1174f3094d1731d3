"""An MS2000 daemon killed with SIGKILL during `SS Z` always restarts with the old or the new saved
settings, never a corrupt file nor leftover temporary files (MS-111, emulator/storage/nvstore.py)."""

from __future__ import annotations

from pathlib import Path

from scripts.soak.kill_save import kill_during_save

CYCLES = 5


def test_kill_during_ss_z_leaves_old_or_new_state_ms111(tmp_path: Path) -> None:
    figures = kill_during_save(CYCLES, tmp_path / "state", workdir=tmp_path / "runs")
    assert figures["kept_new"] + figures["kept_old"] == CYCLES, figures
