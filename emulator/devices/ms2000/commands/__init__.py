"""Handlers of the base command set (§2.3 rows marked base), keyed by command shortcut."""

from __future__ import annotations

from functools import partial

from emulator.devices.ms2000.calls import Handler, Reply
from emulator.devices.ms2000.commands.motion import MotionCommands
from emulator.devices.ms2000.commands.settings import SettingsCommands
from emulator.devices.ms2000.commands.system import SystemCommands


class BaseCommands(MotionCommands, SettingsCommands, SystemCommands):
    """Every base command of the controller."""

    def table(self) -> dict[str, Handler]:
        return {
            "AA": self.aa,
            "AC": self.accel,
            "AZ": self.azero,
            "B": self.backlash,
            "BCA": self.bcustom,
            "BE": self.benable,
            "BU": self.build,
            "CD": lambda call: Reply.text(self.controller.cfg.cdate),
            "C": self.counts,
            "CCA": self.customa,
            "D": self.dack,
            "DU": self.dump,
            "ES": self.ensync,
            "EP": self.epolarity,
            "E": self.error,
            "EX": self.extra,
            "\\": self.halt,
            "H": self.here,
            "!": self.home,
            "I": self.info,
            "J": self.joystick,
            "JS": self.jsspd,
            "KA": partial(self.gain, "ka"),
            "KD": partial(self.gain, "kd"),
            "KI": partial(self.gain, "ki"),
            "KP": partial(self.gain, "kp"),
            "KV": partial(self.gain, "kv"),
            "LCD": self.lcd,
            "LL": self.lladdr,
            "MA": self.maintain,
            "MC": self.motctrl,
            "M": self.move,
            "R": self.movrel,
            "OS": self.overshoot,
            "PC": self.pcros,
            "RA": self.rdadc,
            "RB": self.rdsbyte,
            "RS": self.rdstat,
            "~": self.reset,
            "RT": self.rtime,
            "RU": self.runaway,
            "SP": self.savepos,
            "SS": self.saveset,
            "HM": partial(self.place, "home"),
            "SL": partial(self.place, "soft_lower"),
            "SU": partial(self.place, "soft_upper"),
            "S": self.speed,
            "@": self.spin,
            "/": lambda call: Reply.text("B" if self.controller.busy(call.now) else "N"),
            "SB": self.stopbits,
            "TTL": self.ttl,
            "UM": self.unit_multiplier,
            "UN": self.units,
            "VB": self.vb,
            "VE": self.vector,
            "V": self.version,
            "WT": self.wait,
            "W": self.where,
            "N": lambda call: Reply.text(f":A {self.controller.cfg.who}"),
            "Z2B": self.z2b,
            "Z": self.zero,
        }
