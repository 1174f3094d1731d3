"""`stageemu://PROFILE?timing=fast|realistic&scale=X&state=DIR` (or `stageemu://?profile=PATH`).

PROFILE is a bundled profile name; a profile file goes in `?profile=` (a path does not fit in a URL's
host part). Every problem is a ValueError with a one-line message, pyserial's convention for URLs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from emulator.clock import check_scale
from emulator.line import REALISTIC, TIMINGS

SCHEME = "stageemu"
PARAMETERS = ("profile", "timing", "scale", "state")
FORM = f"{SCHEME}://PROFILE[?timing=fast|realistic&scale=X&state=DIR] or {SCHEME}://?profile=PATH[&...]"


@dataclass(frozen=True)
class UrlOptions:
    """What a `stageemu://` URL asks for."""

    profile: str
    timing: str = REALISTIC
    #: device seconds per wall second (1: real time)
    scale: float = 1.0
    #: where the device keeps its non-volatile memory; None: in memory, gone at close
    state_dir: Path | None = None


def parse_url(url: str) -> UrlOptions:
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
    return UrlOptions(
        profile=_profile(url, parts.netloc, values.get("profile")),
        timing=_timing(url, values.get("timing", REALISTIC)),
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
