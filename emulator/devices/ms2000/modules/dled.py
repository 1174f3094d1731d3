"""DLED: the two-channel current-mode LED driver (§9.8, MS-LED-4, MS-LED-5).

`LED X=pct Y=pct` set the two channel currents (0–100 %, about 900 mA at 100 %); `LED R=max` and
`LED T=max` the maxima of channels X and Y (0–100). A brightness above its channel's maximum is
limited to it when set, and lowering a maximum limits the brightness already set [choice]. The
maxima are remembered on the board as soon as they change (MS-111); the brightnesses are saved
with `SS Z` [choice, as LED DIMMER]. Queries reply value first: `X=10 :A` (MS-LED-2).

Outside IN0 modes 20–23 both channels shine at their set brightness. In those modes the channels
are dark until IN0 lights them (MS-LED-5): 20 — every rising edge lights all channels for `RT Y`
ms; 21 — every edge lights only the next channel for `RT Y` ms, in turn X, Y, X…, skipping
channels at 0 %; 22 and 23 — as 20 and 21, but lit until IN0 falls. An edge while lit restarts
the time [choice]. Observable `led {x, y}` gives what each channel emits now (%), each change is a
`led` event.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import Call, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import AutoSettings, ControlChannel, LcdSegment, TtlIn
from emulator.devices.ms2000.modules.events import In0ModeChanged, Reset, on

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

CHANNELS = ("X", "Y")
#: the maximum letter of each channel (MS-LED-4)
MAX_LETTER = {"X": "R", "Y": "T"}
ALL_TIMED, NEXT_TIMED, ALL_LEVEL, NEXT_LEVEL = 20, 21, 22, 23
GATED_MODES = frozenset({ALL_TIMED, NEXT_TIMED, ALL_LEVEL, NEXT_LEVEL})
#: modes that light every channel; the others light one at a time
ALL_MODES = frozenset({ALL_TIMED, ALL_LEVEL})
#: modes whose light ends after `RT Y`; the others end when IN0 falls
TIMED_MODES = frozenset({ALL_TIMED, NEXT_TIMED})
#: the drive current at 100 % (MS-LED-4)
FULL_SCALE_MA = 900.0
FACTORY_LEVELS = {"X": 0, "Y": 0}
FACTORY_MAXIMA = {"X": 100, "Y": 100}


@register
class Dled(Module, AutoSettings, TtlIn, LcdSegment, ControlChannel):
    name = "DLED"
    in0_modes = GATED_MODES
    observable = "led"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.levels = dict(FACTORY_LEVELS)
        self.maxima = dict(FACTORY_MAXIMA)
        #: channels IN0 has lit in modes 20–23
        self.lit: set[str] = set()
        #: the channel mode 21/23 lit last (the next edge lights the one after it)
        self.last: str | None = None
        self._timer: Timer | None = None
        self._shown = self.output()

    # ---- the command (MS-LED-4) ---------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        return {"LED": self.led}

    def led(self, call: Call) -> Reply:
        """LED X/Y brightness, R/T maxima, all 0–100."""
        now = call.now
        percent = within(0, 100, integer=True)

        changed: list[str] = []

        def level(channel: str) -> Param:
            def store(value: float) -> None:
                self.levels[channel] = int(value)

            # limited once the whole command is applied, so `LED X=50 R=10` = `LED R=10 X=50`
            return Param(lambda: self._limited(channel), store, percent)

        def maximum(channel: str) -> Param:
            def store(value: float) -> None:
                if int(value) != self.maxima[channel]:
                    self.maxima[channel] = int(value)
                    changed.append(channel)

            return Param(lambda: self.maxima[channel], store, percent)

        params = {**{c: level(c) for c in CHANNELS}, **{MAX_LETTER[c]: maximum(c) for c in CHANNELS}}
        reply = run_settings(call, params, "XYTR", self.controller.render(call.key), self.controller.ack())
        self.levels = {c: self._limited(c) for c in CHANNELS}
        if changed:
            self.controller.limits_changed()  # the maxima are remembered at once (MS-111)
        self._show(now)
        return reply

    def _limited(self, channel: str) -> int:
        return min(self.levels[channel], self.maxima[channel])

    # ---- IN0 modes 20–23 (MS-LED-5) -----------------------------------------------------------

    def output(self) -> dict[str, int]:
        """What each channel emits now (%): its level, unless an IN0 mode keeps it dark."""
        gated = self.controller.card.ttl_in in GATED_MODES
        return {c: self.levels[c] if not gated or c in self.lit else 0 for c in CHANNELS}

    def _show(self, now: float) -> None:
        shown = self.output()
        if shown != self._shown:
            self._shown = shown
            self.controller.push_event({"ev": "led", "x": shown["X"], "y": shown["Y"], "t": now})

    def _light(self, channels: set[str], now: float) -> None:
        self.lit = channels
        self._show(now)

    def _cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _next_channel(self) -> str | None:
        """The channel after the last one lit, skipping channels at 0 % (None: all dark)."""
        start = CHANNELS.index(self.last) + 1 if self.last is not None else 0
        for step in range(len(CHANNELS)):
            channel = CHANNELS[(start + step) % len(CHANNELS)]
            if self.levels[channel] > 0:
                return channel
        return None

    def in0_trigger(self, mode: int, now: float) -> None:
        self._cancel()
        if mode in ALL_MODES:
            channels = set(CHANNELS)
        else:
            channel = self._next_channel()
            if channel is None:
                self._light(set(), now)
                return
            self.last = channel
            channels = {channel}
        self._light(channels, now)
        if mode in TIMED_MODES:
            self._timer = self.controller.at(now + self.controller.card.rt_pulse_ms / 1000, self._timed_out)

    def _timed_out(self, now: float) -> None:
        self._timer = None
        self._light(set(), now)

    def in0_release(self, mode: int, now: float) -> None:
        if mode not in TIMED_MODES:
            self._light(set(), now)

    @on(In0ModeChanged)
    def in0_mode_changed(self, event: In0ModeChanged) -> None:
        """A new IN0 mode starts dark and from channel X (MS-LED-5)."""
        self._cancel()
        self.last = None
        self._light(set(), event.t)

    # ---- reports, SS Z and the remembered maxima ----------------------------------------------

    def lcd_segment(self, now: float) -> str | None:
        return f"L {self.levels['X']}"  # §9.0 [choice]

    def observe(self, now: float) -> Any:
        shown = self.output()
        return {
            "x": shown["X"],
            "y": shown["Y"],
            "x_ma": shown["X"] * FULL_SCALE_MA / 100,
            "y_ma": shown["Y"] * FULL_SCALE_MA / 100,
            "levels": {c.lower(): v for c, v in self.levels.items()},
            "maxima": {c.lower(): v for c, v in self.maxima.items()},
        }

    @on(Reset)
    def reset(self, event: Reset) -> None:
        now = event.t
        # brightness saved by `SS Z` before a maximum was lowered is limited to it
        self.levels = {c: self._limited(c) for c in CHANNELS}
        self._cancel()
        self.lit = set()
        self.last = None
        self._show(now)

    def save(self) -> dict[str, Any]:
        return dict(self.levels)

    def restore(self, data: dict[str, Any] | None) -> None:
        self.levels = _channels(FACTORY_LEVELS, data)

    def save_auto(self) -> dict[str, Any]:
        return dict(self.maxima)

    def restore_auto(self, data: dict[str, Any] | None) -> None:
        self.maxima = _channels(FACTORY_MAXIMA, data)


def _channels(factory: dict[str, int], data: dict[str, Any] | None) -> dict[str, int]:
    """Stored per-channel percentages; anything else keeps the factory value."""
    values = dict(factory)
    for key, value in (data or {}).items():
        if key in values and isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 100:
            values[key] = value
    return values
