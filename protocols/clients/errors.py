"""What both clients raise alike, so `protocols.clients` exports one `NoReply` for either device."""

from __future__ import annotations


class NoReply(Exception):
    """The reply did not arrive (completely) before the timeout."""
