"""`stage-emu capture`: a profile from a real controller, read with read-only commands only.

One module per concern:
- `readings`: a query as sent, a reading (a profile field and what a reply gave it), the transcript
  of what was sent with the notes the profile keeps as comments;
- `wire`: opening the port (any pyserial device or URL) and one exchange per query;
- `ms2000` (its queries and their read-only check), `ms2000_replies` (how its replies map to
  fields), `mp285` (both): each family's part;
- `closest`: the bundled profile to extend and the fewest keys that reproduce every reading;
- `yamlout`: the profile text (comment header, keys in `describe` order) and loading it back;
- `run`: the whole capture (`capture`, `dry_run`).
"""

from emulator.tools.capture.readings import CaptureBug, CaptureError
from emulator.tools.capture.run import FAMILIES, Capture, capture, dry_run
from emulator.tools.capture.wire import LineOptions

__all__ = ["FAMILIES", "Capture", "CaptureBug", "CaptureError", "LineOptions", "capture", "dry_run"]
