"""`stageemu://PROFILE?timing=fast|realistic&time=real|virtual&scale=X&state=DIR` (or
`stageemu://?profile=PATH`): a new device of its own; `stageemu://?attach=KEY[&channel=NAME]`: a port
on a device already served in this process (`HostedDevice.url`, the pytest plugin's virtual time).

PROFILE is a bundled profile name; a profile file goes in `?profile=` (a path does not fit in a URL's
host part). Every problem is a ValueError with a one-line message, pyserial's convention for URLs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from emulator.device import MAIN
from emulator.hosting.clock import check_scale
from emulator.wire_time import REALISTIC, TIMINGS

SCHEME = "stageemu"
PARAMETERS = ("profile", "timing", "time", "scale", "state", "attach", "channel")
FORM = (
    f"{SCHEME}://PROFILE[?timing=fast|realistic&time=real|virtual&scale=X&state=DIR] "
    f"or {SCHEME}://?profile=PATH[&...] or {SCHEME}://?attach=KEY[&channel=NAME]"
)
REAL = "real"
VIRTUAL = "virtual"


@dataclass(frozen=True)
class UrlOptions:
    """What a `stageemu://` URL asks for."""

    profile: str
    timing: str = REALISTIC
    #: REAL: device time runs with the wall clock (times `scale`); VIRTUAL: it passes only when the
    #: host waits, at once (emulator/urlhandler/hosted.py)
    time: str = REAL
    #: device seconds per wall second (1: real time)
    scale: float = 1.0
    #: where the device keeps its non-volatile memory; None: in memory, gone at close
    state_dir: Path | None = None


@dataclass(frozen=True)
class AttachOptions:
    """A `stageemu://?attach=KEY` URL: a port on channel `channel` of the device served as KEY."""

    key: str
    channel: str = MAIN


def parse_url(url: str) -> UrlOptions | AttachOptions:
    """The options of `url`; ValueError naming the problem and the expected form."""
    try:
        parts = urlsplit(url)
    except ValueError as exc:
        raise ValueError(f"{url!r}: not a URL ({exc}); expected {FORM}") from None
    if parts.scheme.lower() != SCHEME:
        raise ValueError(f"{url!r}: not a {SCHEME}:// URL; expected {FORM}")
    if parts.path not in ("", "/") or parts.fragment:
        raise ValueError(f"{url!r}: unexpected {parts.path or '#' + parts.fragment!r}; expected {FORM}")
    try:
        query = parse_qs(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError:
        raise ValueError(f"{url!r}: malformed query {parts.query!r}; expected {FORM}") from None
    values: dict[str, str] = {}
    for key, given in query.items():
        if key not in PARAMETERS:
            raise ValueError(f"{url!r}: unknown parameter {key!r} (known: {', '.join(PARAMETERS)})")
        if len(given) > 1:
            raise ValueError(f"{url!r}: parameter {key!r} given {len(given)} times")
        values[key] = given[0]
    if "attach" in values:
        if parts.netloc or set(values) - {"attach", "channel"}:
            raise ValueError(f"{url!r}: attach= takes only channel= beside it; expected {FORM}")
        if not values["attach"] or not values.get("channel", MAIN):
            raise ValueError(f"{url!r}: attach= and channel= need a name")
        return AttachOptions(values["attach"], values.get("channel", MAIN))
    if "channel" in values:
        raise ValueError(f"{url!r}: channel= goes with attach=; a new device's port is its main one")
    time = values.get("time", REAL)
    if time not in (REAL, VIRTUAL):
        raise ValueError(f"{url!r}: time must be {REAL} or {VIRTUAL}, got {time!r}")
    if time == VIRTUAL and "scale" in values:
        raise ValueError(f"{url!r}: scale has no meaning in virtual time (it passes as the host waits)")
    return UrlOptions(
        profile=_profile(url, parts.netloc, values.get("profile")),
        timing=_timing(url, values.get("timing", REALISTIC)),
        time=time,
        scale=_scale(url, values.get("scale", "1")),
        state_dir=_state_dir(url, values.get("state")),
    )


def _profile(url: str, host: str, parameter: str | None) -> str:
    if host and parameter is not None:
        raise ValueError(f"{url!r}: a profile in the host part ({host!r}) and in ?profile=; give one")
    profile = host or parameter
    if not profile:
        raise ValueError(f"{url!r}: no profile; expected {FORM}")
    return profile


def _timing(url: str, value: str) -> str:
    if value not in TIMINGS:
        raise ValueError(f"{url!r}: timing must be one of {', '.join(TIMINGS)}, got {value!r}")
    return value


def _scale(url: str, value: str) -> float:
    try:
        return check_scale(float(value))
    except ValueError as exc:
        raise ValueError(f"{url!r}: scale: {exc}") from None


def _state_dir(url: str, value: str | None) -> Path | None:
    if value is None:
        return None
    if not value:
        raise ValueError(f"{url!r}: state needs a directory (state=DIR)")
    return Path(value).expanduser()
