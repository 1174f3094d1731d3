"""NO CHANGE SETTINGS (§7, MS-109): write protection beyond TV-91 and TV-92 (tests/conformance/ms2000)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"

REFUSED = b":N-4\r\n"


@pytest.fixture
def ms(make: Callable[..., Harness]) -> Harness:
    return make(ALL_MODULES)


def test_protected_commands_still_answer_queries(ms: Harness) -> None:
    """MS-109 [choice]: only writes are refused; a query-only line answers, a mixed one does not."""
    ms.cmd("VB T=1027")
    assert ms.cmd("S X? Y?") == b":A X=5.145600 Y=5.145600\r\n"
    assert ms.cmd("S X=1 Y?") == REFUSED
    assert ms.cmd("S X?") == b":A X=5.145600\r\n"


def test_actions_and_bare_forms_are_refused(ms: Harness) -> None:
    """MS-109 [choice]: protected MOVE, HOME and SAVESET refuse every non-query form."""
    for code in (1018, 1012, 1044):
        assert ms.cmd(f"VB T={code}") == ACK
    assert ms.cmd("M X=1000") == REFUSED
    assert ms.cmd("! X") == REFUSED
    assert ms.cmd("SS Z") == REFUSED
    assert ms.cmd("SS") == REFUSED
    assert ms.get("busy") is False
    assert ms.cmd("R X=1000") == ACK  # MOVREL (no number in the table) is not protected


def test_module_commands_can_be_protected(ms: Harness) -> None:
    """MS-109: PEDAL is number 41, RBMODE 21."""
    assert ms.cmd("VB T=1041") == ACK
    assert ms.cmd("PD X=0.01") == REFUSED
    assert ms.cmd("PD X?") == b":A X=0.001000\r\n"
    assert ms.cmd("VB T=1021") == ACK
    assert ms.cmd("RM") == REFUSED
    assert ms.get("no_change_settings") == {"protected": ["PD", "RM"]}


def test_unknown_numbers_and_read_back(ms: Harness) -> None:
    """MS-109: numbers missing from the table are `:N-4`; `VB T?` reads the last code [choice];
    items are validated together (MS-27)."""
    assert ms.cmd("VB T?") == b":A T=0\r\n"
    assert ms.cmd("VB T=1005") == REFUSED
    assert ms.cmd("VB T=84") == REFUSED
    assert ms.cmd("VB T=2027") == REFUSED
    assert ms.cmd("VB T=1027.5") == REFUSED
    assert ms.cmd("VB X=99 T=1027") == REFUSED
    assert ms.cmd("S X=1") == ACK
    assert ms.cmd("VB X=1 T=1001") == ACK
    assert ms.cmd("VB X? T?") == b":A X=1 T=1001\r\n"


def test_protection_is_saved_with_ss_z(make: Callable[..., Harness], tmp_path: Path) -> None:
    """MS-109, MS-111, MS-112: saved by `SS Z`; a reset returns to the saved protections."""
    ms = make(ALL_MODULES, state_dir=tmp_path)
    ms.cmd("VB T=1027")
    ms.cmd("~")
    assert ms.cmd("S X=1") == ACK
    ms.cmd("VB T=1027")
    ms.cmd("SS Z")
    ms.settle()
    ms.output()
    ms.cmd("VB T=27")
    ms.cmd("~")
    assert ms.cmd("S X=2") == REFUSED
    ms.input("power_cycle")
    assert ms.cmd("S X=2") == REFUSED


def test_protecting_vb_itself_is_impossible(ms: Harness) -> None:
    """MS-109: VB has no number in the table, so the protection can always be released."""
    ms.cmd("VB T=1075")
    assert ms.cmd("RT X=300") == REFUSED
    assert ms.cmd("VB T=75") == ACK
    assert ms.cmd("RT X=300") == ACK
