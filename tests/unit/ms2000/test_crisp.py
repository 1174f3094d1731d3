"""CRISP (§9.5) on the manual clock: the rest of MS-CRISP-1…MS-CRISP-9 beyond the test vectors,
which run in tests/conformance/ms2000 (TV-157…TV-168)."""

from __future__ import annotations

import pytest

from emulator.device import ControlError
from emulator.devices.ms2000.calls import Reply
from emulator.devices.ms2000.modules import MODULES, Handler, Module
from emulator.devices.ms2000.modules.crisp_commands import CrispCommands
from emulator.devices.ms2000.modules.moduleset import ModuleSet
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def crisp() -> Harness:
    return Harness("ms2000-crisp")


def state(h: Harness) -> bytes:
    return h.cmd("LK X?")


def z_units(h: Harness) -> int:
    return int(h.cmd("W Z")[3:-2])


def locked_in_focus(h: Harness) -> Harness:
    assert h.cmd("LK") == ACK and h.cmd("LK F=83") == ACK
    h.wait(0.2)
    assert state(h) == b":A F\r\n"
    return h


def test_calibrations_and_dither_ms_crisp_2(crisp: Harness) -> None:
    """MS-CRISP-2/3: log-amp calibration `H` 0.5 s then `G`; `LK` → dither `f` → gain calibration
    `C`, `1`…`5` (0.2 s each), which sets `LR X` from the slope and ends in `R`."""
    crisp.cmd("LR X=7")
    assert crisp.cmd("LK F=72") == ACK
    assert state(crisp) == b":A H\r\n"
    crisp.wait(0.49)
    assert state(crisp) == b":A H\r\n"
    crisp.wait(0.02)
    assert state(crisp) == b":A G\r\n"
    assert crisp.cmd("LK M?") == b":A 188 \r\n"
    crisp.cmd("LK")
    assert state(crisp) == b":A f\r\n"
    crisp.cmd("LK")
    steps = []
    for _ in range(13):
        steps.append(crisp.get("crisp")["state"])
        crisp.wait(0.1)
    assert [s for i, s in enumerate(steps) if i == 0 or s != steps[i - 1]] == list("C12345R")
    assert crisp.cmd("LR X?") == b":A X=100.000000\r\n"
    assert crisp.cmd("W Z") == b":A 0\r\n"


def test_failed_gain_calibration_and_dim(crisp: Harness) -> None:
    """MS-CRISP-2: a dim signal gives `D` (bare `LK` retries); a saturated error has no slope: `E`."""
    crisp.input("crisp", sum=50)
    crisp.cmd("LK")
    assert state(crisp) == b":A D\r\n"
    crisp.cmd("LK")
    assert state(crisp) == b":A D\r\n"
    crisp.input("crisp", sum=3000, surface_um=500)
    crisp.cmd("LK")
    crisp.cmd("LK F=67")
    crisp.wait(1.3)
    assert state(crisp) == b":A E\r\n"
    assert crisp.cmd("LR X?") == b":A X=100.000000\r\n"


def test_dim_signal_loses_lock(crisp: Harness) -> None:
    locked_in_focus(crisp)
    crisp.input("crisp", sum=99)
    assert state(crisp) == b":A E\r\n"


def test_offset_reset_returns_to_previous_state(crisp: Harness) -> None:
    """MS-CRISP-3: 111 clears `LK Z` through `o` and `l`, then the previous state."""
    locked_in_focus(crisp)
    crisp.cmd("LK Z=30")
    crisp.wait(0.3)
    assert crisp.cmd("LK F=111") == ACK
    assert state(crisp) == b":A o\r\n"
    crisp.wait(0.011)
    assert state(crisp) == b":A l\r\n" and crisp.cmd("LK Z?") == b":A 0 \r\n"
    crisp.wait(0.01)
    assert state(crisp) in (b":A K\r\n", b":A F\r\n")
    crisp.wait(0.3)
    assert state(crisp) == b":A F\r\n" and abs(z_units(crisp)) <= 1  # one encoder count: 0.05 µm


def test_commanded_focus_move_inhibits_lock(crisp: Harness) -> None:
    """MS-CRISP-2: `N` while a commanded Z move runs, `K` after, and the lock pulls focus back."""
    locked_in_focus(crisp)
    assert crisp.cmd("M Z=100") == ACK
    assert state(crisp) == b":A N\r\n"
    crisp.idle()
    assert state(crisp) == b":A K\r\n"
    crisp.wait(0.5)
    assert state(crisp) == b":A F\r\n" and abs(z_units(crisp)) <= 1  # one encoder count: 0.05 µm
    assert crisp.cmd("M X=1000") == ACK and state(crisp) == b":A F\r\n"


def test_wheel_moves_lock_offset(crisp: Harness) -> None:
    """MS-CRISP-6: while locked the wheel changes `LK Z` by counts × `UL Z`, not the axis."""
    locked_in_focus(crisp)
    crisp.input("wheel", counts=10)
    assert crisp.cmd("LK Z?") == b":A 20 \r\n"
    crisp.wait(0.5)
    assert abs(z_units(crisp) + 2) <= 1  # the lock point moved 0.2 µm down, to one encoder count
    crisp.cmd("UL")
    crisp.input("wheel", counts=10)
    assert crisp.cmd("LK Z?") == b":A 20 \r\n"


def test_out0_mode_11_pulse_after_move_in_focus(crisp: Harness) -> None:
    """MS-CRISP-7: in OUT0 mode 11 `/` is `B` until the lock is back in `F` after a move; then
    OUT0 pulses `RT Y` ms."""
    locked_in_focus(crisp)
    assert crisp.cmd("TTL Y=11") == ACK
    crisp.cmd("RT Y=20")
    crisp.take_events()
    crisp.cmd("M Z=50")
    while crisp.dev.axes[2].busy(crisp.t):
        assert crisp.cmd("/") == b"B\r\n"
        crisp.wait(0.005)
    while crisp.cmd("/") == b"B\r\n":
        assert state(crisp) in (b":A K\r\n", b":A N\r\n")
        crisp.wait(0.005)
    assert state(crisp) == b":A F\r\n"
    crisp.wait(0.05)
    levels = [(e["level"], round(e["t"], 3)) for e in crisp.take_events("ttl_out0")]
    assert [level for level, _ in levels] == [1, 0]
    assert levels[1][1] - levels[0][1] == pytest.approx(0.02)


def test_settings_saved_and_focus_index_after_reset(crisp: Harness) -> None:
    """MS-CRISP-5: every setting and the calibration are saved with `SS Z`; `UL F` takes effect at
    reset."""
    crisp.cmd("LR X=321 Y=1.3 Z=0.5 T=6")
    crisp.cmd("UL X=50 Y=20 Z=3 F=1")
    crisp.cmd("AL X=7 Y=8")
    crisp.cmd("LK Z=12 M=40")
    crisp.cmd("EXTRA Z=3")
    assert crisp.dev.focus_axis() is crisp.dev.axis_named("Z")
    assert crisp.cmd("SS Z") == ACK
    crisp.input("power_cycle")
    assert (
        crisp.cmd("LR X? Y? Z? F? T?") == b":A X=321.000000 Y=1.300000 Z=0.500000 F=0.002500 T=6.000000\r\n"
    )
    assert crisp.cmd("UL X? Y? Z? F?") == b":A X=50.000000 Y=20.000000 Z=3.000000 F=1.000000\r\n"
    assert crisp.cmd("AL X? Y? Z?") == b":A X=7.000000 Y=8.000000 Z=0.000050\r\n"
    assert crisp.cmd("LK Z? M?") == b":A 12 40 \r\n"
    assert crisp.cmd("EXTRA Z?") == b":A Z=3.000000\r\n"
    assert crisp.dev.focus_axis() is crisp.dev.axis_named("Y")
    assert state(crisp) == b":A I\r\n"


def test_bad_input_changes_nothing(crisp: Harness) -> None:
    """MS-27, MS-30, MS-40: out of range `:N-4`, unknown letters `:N-2`, nothing applied."""
    before = crisp.cmd("LR X? Y? Z? F? T?")
    for bad in ("LR Y=2 Z=0.5", "LR Y=0.05", "LR F=0", "LR Z=11", "UL F=3", "UL X=101", "AL X=256", "AL Z=0"):
        assert crisp.cmd(bad) == b":N-4\r\n", bad
    assert crisp.cmd("LR Y=1 Q=1") == b":N-2\r\n"
    assert crisp.cmd("LR X? Y? Z? F? T?") == before
    for bad in ("LK Z=3000", "LK M=256", "LK Y=3", "LK T=1", "LK Z=1 F=200", "EXTRA Z=101", "EXTRA X=1"):
        assert crisp.cmd(bad) == b":N-4\r\n", bad
    assert crisp.cmd("LK Q?") == b":N-2\r\n" and crisp.cmd("EXTRA Q?") == b":N-2\r\n"
    assert crisp.cmd("LK Z? M?") == b":A 0 0 \r\n" and state(crisp) == b":A I\r\n"


def test_extra_m_stays_the_base_command(crisp: Harness) -> None:
    """MS-86: `EXTRA M?` reads the button-flag byte beside CRISP's letters."""
    assert crisp.cmd("EXTRA M?") == b":A 0\r\n"
    assert crisp.cmd("EXTRA") == b":N-3\r\n"


def test_halt_ends_routines_but_keeps_lock(crisp: Harness) -> None:
    """MS-76 [choice]: HALT ends a calibration (`R`) or a focus curve (`end`, previous state) and
    leaves a lock engaged."""
    crisp.cmd("LK")
    crisp.cmd("LK F=67")
    crisp.wait(0.3)
    crisp.cmd("\\")
    assert state(crisp) == b":A R\r\n"
    crisp.cmd("LK F=97")
    crisp.wait(0.2)
    crisp.output()
    assert crisp.send(b"\\\r").endswith(b"end\r\n:A\r\n")
    assert state(crisp) == b":A R\r\n"
    locked_in_focus(crisp)
    crisp.cmd("\\")
    assert state(crisp) == b":A F\r\n"


def test_at_button_and_button_functions(crisp: Harness) -> None:
    """MS-85, Appendix B: a normal `@` press advances; held > 10 s resets the offset; `BE F=11/12`."""
    crisp.input("button", name="at", ms=100)
    crisp.wait(0.2)
    assert state(crisp) == b":A R\r\n"
    assert crisp.cmd("BE F=11") == ACK and state(crisp) in (b":A K\r\n", b":A F\r\n")
    crisp.cmd("LK Z=9")
    crisp.input("button", name="at", ms=10_500)
    crisp.wait(11)
    assert crisp.cmd("LK Z?") == b":A 0 \r\n"
    crisp.cmd("LK Z=9")
    assert crisp.cmd("BE F=12") == ACK
    crisp.wait(0.05)
    assert crisp.cmd("LK Z?") == b":A 0 \r\n"


def test_criff_directive_name_ms_102() -> None:
    """MS-102: knob `crisp_directive_name` prints `CRIFF`; the profile still names CRISP."""
    h = Harness("ms2000-crisp", {"knobs": {"crisp_directive_name": "CRIFF"}})
    assert h.cmd("BU X").endswith(b"\rINO_INT\rCRIFF\r\n")
    assert h.cmd("LK X?") == b":A I\r\n"


def test_commands_need_the_module_ms_118(ms: Harness) -> None:
    for command in ("LK X?", "LR Y?", "UL X?", "AL Z?"):
        assert ms.cmd(command) == b":N-1\r\n"
    assert ms.cmd("EXTRA X?") == b":N-2\r\n"
    assert ms.cmd("TTL X=9") == b":N-4\r\n" and ms.cmd("TTL Y=12") == b":N-4\r\n"


def test_piezo_build_locks_and_drives_dac() -> None:
    """ms2000-pz-crisp (A.2): the lock follows drift on the ±50 µm piezo, the DAC follows Z."""
    h = Harness("ms2000-pz-crisp")
    locked_in_focus(h)
    h.input("crisp", drift_um_per_s=2)
    h.wait(5)
    assert h.get("crisp")["state"] == "F"
    assert h.get("axes")["Z"]["user_mm"] == pytest.approx(0.010, abs=2e-4)
    assert h.get("dac_out_v") == pytest.approx(6.0, abs=0.02)


def test_control_input_checks(crisp: Harness) -> None:
    """Appendix B: the `crisp` input checks its parameters before applying any."""
    for params in ({"sum": -1}, {"snr": "x"}, {"surface": 1}, {"drift_um_per_s": float("nan")}):
        with pytest.raises(ControlError):
            crisp.input("crisp", **params)
    assert crisp.input("crisp", snr=12.5)["snr"] == 12.5


class _Claimer(Module):
    """A stand-in owner of `LK` for the precedence rule (§9.0)."""

    name = "TRACKING"

    def handlers(self) -> dict[str, Handler]:
        return {"LK": lambda call: Reply.text("tracking")}


@pytest.mark.parametrize("order", [("CRISP", "TRACKING"), ("TRACKING", "CRISP")])
def test_crisp_outranks_tracking(
    monkeypatch: pytest.MonkeyPatch, crisp: Harness, order: tuple[str, ...]
) -> None:
    """§9.0: CRISP and TRACKING both claim `LK`/`LR`/`UL`; CRISP wins in either profile order."""
    monkeypatch.setitem(MODULES, "TRACKING", _Claimer)
    table = ModuleSet(crisp.dev, order).handlers()
    assert isinstance(getattr(table["LK"], "__self__", None), CrispCommands)
