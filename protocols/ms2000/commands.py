"""MS2000 command table: long names, shortcuts, aliases and owning firmware modules (MS-19, §2.3)."""

from __future__ import annotations

from dataclasses import dataclass

BASE = "base"


@dataclass(frozen=True)
class CommandSpec:
    """One command word. `key` is the shortcut (or the long name when there is none) and is the name
    used everywhere else: reply-shape overrides, handler tables, summaries."""

    name: str
    short: str | None
    modules: tuple[str, ...] = (BASE,)
    aliases: tuple[str, ...] = ()

    @property
    def key(self) -> str:
        return self.short or self.name

    @property
    def is_base(self) -> bool:
        return BASE in self.modules

    def words(self) -> tuple[str, ...]:
        return tuple(w for w in (self.name, self.short, *self.aliases) if w)


def _c(name: str, short: str | None = None, *modules: str, aliases: tuple[str, ...] = ()) -> CommandSpec:
    return CommandSpec(name, short, modules or (BASE,), aliases)


AUTOFOCUS = "AUTOFOCUS"
CRISP = "CRISP"
TRACKING = "TRACKING"
ARRAY = "ARRAY MODULE"
SCAN = "SCAN MODULE"
RING_BUFFER = "RING BUFFER"
LED_DIMMER = "LED DIMMER"
DLED = "DLED"
INO_INT = "INO_INT"

COMMANDS: tuple[CommandSpec, ...] = (
    _c("AALIGN", "AA"),
    _c("ACCEL", "AC"),
    _c("AFCALIB", "AFC", AUTOFOCUS),
    _c("AFADJ", None, AUTOFOCUS),
    _c("AFINFO", None, AUTOFOCUS),
    _c("AFLIM", "AL", CRISP, AUTOFOCUS),
    _c("AFMOVE", "AM", AUTOFOCUS),
    _c("AFOCUS", "AF", AUTOFOCUS),
    _c("AHOME", "AH", ARRAY),
    _c("AIJ", None, ARRAY),
    _c("ARM", None, "SEQUENCER"),
    _c("ARRAY", "AR", ARRAY),
    _c("AZERO", "AZ"),
    _c("BACKLASH", "B"),
    _c("BCUSTOM", "BCA"),
    _c("BENABLE", "BE"),
    _c("BUILD", "BU"),
    _c("CDATE", "CD"),
    _c("CNTS", "C"),
    _c("CUSTOMA", "CCA"),
    _c("CUSTOMB", "CCB", "PLANAR CORRECTION"),
    _c("DACK", "D"),
    _c("DUMP", "DU"),
    _c("ENSYNC", "ES"),
    _c("EPOLARITY", "EP"),
    _c("ERROR", "E"),
    _c("EXTRA", "EX"),
    _c("HALT", "\\"),
    _c("HERE", "H"),
    _c("HOME", "!"),
    _c("INFO", "I"),
    _c("JOYSTICK", "J"),
    _c("JSSPD", "JS"),
    _c("KA"),
    _c("KD"),
    _c("KI"),
    _c("KP"),
    _c("KV"),
    _c("LCD"),
    _c("LED", None, LED_DIMMER, DLED),
    _c("LLADDR", "LL"),
    _c("LOAD", "LD", RING_BUFFER),
    _c("LOCK", "LK", CRISP, TRACKING),
    _c("LOCKRG", "LR", CRISP, TRACKING),
    _c("MAINTAIN", "MA"),
    _c("MOTCTRL", "MC", aliases=("MOTOCTRL",)),
    _c("MOVE", "M"),
    _c("MOVREL", "R", aliases=("MOVEREL",)),
    _c("MULTIMV", "MM", "MULTIAXIS MOVES"),
    _c("OS"),
    _c("PCROS", "PC"),
    _c("PEDAL", "PD", "PEDALS"),
    _c("RBMODE", "RM", RING_BUFFER),
    _c("RDADC", "RA"),
    _c("RDSBYTE", "RB"),
    _c("RDSTAT", "RS"),
    _c("RESET", "~"),
    _c("RTIME", "RT"),
    _c("RUNAWAY", "RU"),
    _c("SAVEPOS", "SP"),
    _c("SAVESET", "SS"),
    _c("SCAN", "SN", SCAN, ARRAY),
    _c("SCANR", "NR", SCAN),
    _c("SCANV", "NV", SCAN),
    _c("SECURE", None, "SOL_LK", "U_SERVO_LK"),
    _c("SETHOME", "HM"),
    _c("SETLOW", "SL"),
    _c("SETUP", "SU"),
    _c("SI", None, "SEARCH INDEX", "SEEK LIMITS"),
    _c("SPEED", "S"),
    _c("SPIN", "@"),
    _c("STATUS", "/"),
    _c("STOPBITS", "SB"),
    _c("TTL"),
    _c("UM"),
    _c("UNITS", "UN"),
    _c("UNLOCK", "UL", CRISP, TRACKING),
    _c("VB"),
    _c("VECTOR", "VE"),
    _c("VERSION", "V"),
    _c("WAIT", "WT"),
    _c("WHERE", "W"),
    _c("WHO", "N"),
    _c("WRDAC", None, "DAC OUT"),
    _c("Z2B"),
    _c("ZERO", "Z"),
    _c("ZS", None, INO_INT),
)

_BY_WORD: dict[str, CommandSpec] = {w.upper(): spec for spec in COMMANDS for w in spec.words()}
BY_KEY: dict[str, CommandSpec] = {spec.key: spec for spec in COMMANDS}
#: first characters that split off an unmatched command token (MS-19)
SPLIT_CHARS = "\\/!~@"


def lookup(word: str) -> CommandSpec | None:
    """The command a word names (long name, shortcut or alias; case-insensitive, MS-10)."""
    return _BY_WORD.get(word.upper())
